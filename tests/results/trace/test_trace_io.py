"""Tests of heliostep.results.trace.files: the trace file format."""

from __future__ import annotations

import csv
import json

import numpy as np
import pandas as pd
import pyarrow.parquet as pq
import pytest

from heliostep.errors import InputError
from heliostep.results.trace.files import is_complete, read_trace, write_trace


def _trace() -> pd.DataFrame:
    # A jump at t = 1 (two rows), awkward floats and a NaN must survive unchanged.
    return pd.DataFrame(
        {
            "time": [0.0, 0.5, 1.0, 1.0, 2.0],
            "motor.tau": [0.0, 1.0 / 3.0, 0.1, 2.5e-300, -7.0],
            "panel_angle_error": [np.pi, np.nan, 1e20, -0.0, 5.0],
        }
    )


META = {"complete": "false", "unit.motor.tau": "N.m", "unit.time": "s", "note": "a: b, c"}
#: What a CSV keeps of META: the units (the rest of a run's metadata is in its metadata.json).
CSV_META = {"unit.motor.tau": "N.m", "unit.time": "s"}
WINDOW = {"window_start": "2025-01-21T10:00:00+01:00", "timezone": "Europe/Rome"}


@pytest.mark.parametrize(("suffix", "kept"), [(".parquet", META), (".csv", CSV_META)])
def test_round_trip_values_metadata_and_duplicate_times(tmp_path, suffix, kept):
    path = tmp_path / f"trace{suffix}"
    write_trace(_trace(), path, META)
    table, meta = read_trace(path)
    assert meta == kept
    assert list(table.columns) == ["time", "motor.tau", "panel_angle_error"]
    expected = _trace()
    for column in expected.columns:
        # Bit-for-bit equal, NaN where NaN.
        np.testing.assert_array_equal(table[column].to_numpy(), expected[column].to_numpy())
        assert table[column].dtype == np.float64
    assert table["time"].tolist().count(1.0) == 2


@pytest.mark.parametrize(("suffix", "kept"), [(".parquet", {}), (".csv", {"unit.time": "s"})])
def test_time_is_written_first_and_ints_become_floats(tmp_path, suffix, kept):
    path = tmp_path / f"trace{suffix}"
    write_trace(pd.DataFrame({"b": [1, 2], "time": [0, 1]}), path)
    table, meta = read_trace(path)
    assert meta == kept
    assert list(table.columns) == ["time", "b"]
    assert table["b"].dtype == np.float64
    assert table["b"].tolist() == [1.0, 2.0]


def test_csv_layout_is_one_header_row_with_units_then_rows_with_the_local_time_and_degrees(tmp_path):
    path = tmp_path / "t.csv"
    frame = pd.DataFrame({"time": [0.0, 1.0, 1.0], "x": [0.5, 0.5, 2.0], "tilt": [0.0, np.pi / 2, np.pi]})
    write_trace(frame, path, {"complete": True, "unit.x": "m", "unit.tilt": "rad", **WINDOW})
    assert path.read_text().splitlines() == [
        "time [s],local_time,x [m],tilt [deg]",
        "0,2025-01-21T10:00:00.000000+01:00,0.5,0",
        "1,2025-01-21T10:00:01.000000+01:00,0.5,90",
        "1,2025-01-21T10:00:01.000000+01:00,2,180",
    ]
    table, meta = read_trace(path)  # the local time left out, the angle back in radians
    assert list(table.columns) == ["time", "x", "tilt"] and table["tilt"].tolist() == [0.0, np.pi / 2, np.pi]
    assert meta == {"unit.time": "s", "unit.x": "m", "unit.tilt": "rad"}


def test_a_csv_trace_reads_with_pandas_and_the_csv_module_as_they_are(tmp_path):
    """No comment line: the first row is the header for any reader; the local time parses to the site's
    zone and is the window's start plus the seconds, across a change of the clocks (to the microsecond)."""
    path = tmp_path / "t.csv"
    time = np.array([0.0, 1.25, 1.25, 3600.000_000_4, 7200.0])
    window = {"window_start": "2025-03-30T01:30:00+01:00", "timezone": "Europe/Rome"}  # 02:00 CET is 03:00 CEST
    write_trace(
        pd.DataFrame({"time": time, "omega": [0.0, 1.0, 2.0, 3.0, 4.0]}), path, {"unit.omega": "rad/s", **window}
    )
    with open(path, newline="", encoding="utf-8") as fh:
        rows = list(csv.reader(fh))
    assert rows[0] == ["time [s]", "local_time", "omega [deg/s]"] and len(rows) == 6
    assert [row[1][-6:] for row in rows[1:]] == ["+01:00", "+01:00", "+01:00", "+02:00", "+02:00"]
    table = pd.read_csv(path)
    assert list(table.columns) == rows[0] and table["time [s]"].tolist() == time.tolist()
    stamps = pd.to_datetime(table["local_time"], utc=True).dt.tz_convert("Europe/Rome")
    start = pd.Timestamp("2025-03-30T01:30:00", tz="Europe/Rome")
    assert stamps.tolist() == [start + pd.Timedelta(microseconds=round(t * 1e6)) for t in time]
    assert stamps.iloc[3] == pd.Timestamp("2025-03-30T03:30:00", tz="Europe/Rome")
    assert table["omega [deg/s]"].tolist() == [float(np.degrees(v)) for v in [0.0, 1.0, 2.0, 3.0, 4.0]]


def test_csv_values_are_the_shortest_text_that_reads_back_the_same_double(tmp_path):
    """Each value written as the shortest decimal that parses to the same double (Python's repr is that
    text, up to its ``.0`` and exponent spelling), NaN as an empty field, names quoted only where needed."""
    rng = np.random.default_rng(7)
    special = [0.0, -0.0, 5e-324, 2.2250738585072014e-308, 1e-100, -1e-7, 1e-6, 0.1, 1 / 3, 1e20, 1.5e300, np.inf]
    values = np.concatenate(
        [special, -np.array(special), rng.standard_normal(200) * 10.0 ** rng.integers(-12, 12, 200)]
    )
    path = tmp_path / "t.csv"
    frame = pd.DataFrame({"time": np.arange(len(values), dtype=float), 'a,"b"': values})
    frame.loc[3, 'a,"b"'] = np.nan
    write_trace(frame, path)
    lines = path.read_text().splitlines()
    assert lines[0] == 'time [s],"a,""b"""'
    fields = [line.split(",")[1] for line in lines[1:]]
    for text, value in zip(fields, frame['a,"b"']):
        if np.isnan(value):
            assert text == ""
            continue
        assert float(text) == value and np.signbit(float(text)) == np.signbit(value)
        digits = lambda t: len(t.lower().split("e")[0].replace("-", "").replace(".", "").strip("0"))  # noqa: E731
        assert digits(text) <= max(digits(repr(value)), 1), (text, repr(value))  # no longer than repr's digits
    table, _ = read_trace(path)
    np.testing.assert_array_equal(table['a,"b"'].to_numpy(), frame['a,"b"'].to_numpy())  # bit for bit


def test_hand_written_csv_is_read(tmp_path):
    path = tmp_path / "ref.csv"
    path.write_text("\ntime,x [m],tilt [deg],note\n0,1,90,3\n1,2.5,45,4\n")
    table, meta = read_trace(path)
    assert meta == {"unit.x": "m", "unit.tilt": "rad"}
    assert table["x"].tolist() == [1.0, 2.5] and table["note"].tolist() == [3.0, 4.0]
    assert table["tilt"].tolist() == [np.pi / 2, np.pi / 4]


def test_a_runs_trace_csv_has_the_rest_of_its_metadata_in_the_metadata_json_beside_it(tmp_path):
    write_trace(_trace(), tmp_path / "trace.csv", META)
    record = {"complete": False, "trace": META}  # (as a run writes it: the trace's metadata under "trace")
    (tmp_path / "metadata.json").write_text(json.dumps(record))
    assert read_trace(tmp_path / "trace.csv")[1] == META
    (tmp_path / "other.csv").write_bytes((tmp_path / "trace.csv").read_bytes())
    assert read_trace(tmp_path / "other.csv")[1] == CSV_META  # another file's: only its header's
    (tmp_path / "metadata.json").write_text("{not json")
    with pytest.raises(InputError, match=r"metadata\.json: cannot read"):
        read_trace(tmp_path / "trace.csv")


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("time [ms],x\n0,1\n", r"bad\.csv: column 'time \[ms\]': the time is in seconds"),
        ("# complete: true\ntime,x\n0,1\n", r"bad\.csv: no 'time' column"),  # a comment line is no header
    ],
)
def test_a_time_in_other_units_and_a_comment_line_are_refused(tmp_path, text, message):
    path = tmp_path / "bad.csv"
    path.write_text(text)
    with pytest.raises(InputError, match=message):
        read_trace(path)


def test_parquet_metadata_is_schema_key_value_metadata(tmp_path):
    path = tmp_path / "t.parquet"
    write_trace(pd.DataFrame({"time": [0.0], "x": [1.0]}), path, {"complete": "true"})
    schema_meta = pq.read_schema(path).metadata
    assert schema_meta[b"complete"] == b"true"


def test_parquet_columns_are_byte_stream_split_and_zstd_not_a_dictionary(tmp_path):
    """Every float64 column is stored as its byte planes, zstd-compressed (readable by any
    Parquet reader: the encoding is in the format since 2.8); a continuous signal gets no
    dictionary, which it would overflow."""
    path = tmp_path / "t.parquet"
    rng = np.random.default_rng(0)
    write_trace(
        pd.DataFrame({"time": np.arange(5000.0), "x": rng.normal(size=5000), "held": np.repeat([0.0, 1.5], 2500)}),
        path,
        {},
    )
    chunks = pq.ParquetFile(path).metadata.row_group(0)
    for i in range(chunks.num_columns):
        column = chunks.column(i)
        assert "BYTE_STREAM_SPLIT" in column.encodings, (column.path_in_schema, column.encodings)
        assert "PLAIN_DICTIONARY" not in column.encodings and "RLE_DICTIONARY" not in column.encodings
        assert column.compression == "ZSTD"
        assert not column.has_dictionary_page


def test_complete_flag():
    assert is_complete({}) is True
    assert is_complete({"complete": "true"}) is True
    assert is_complete({"complete": "False"}) is False


@pytest.mark.parametrize("suffix", [".parquet", ".csv"])
def test_missing_time_column_names_file_and_column(tmp_path, suffix):
    path = tmp_path / f"bad{suffix}"
    if suffix == ".csv":
        path.write_text("t,x\n0,1\n")
    else:
        pd.DataFrame({"t": [0.0], "x": [1.0]}).to_parquet(path)
    with pytest.raises(InputError, match=r"bad\.(csv|parquet).*'time'"):
        read_trace(path)


def test_decreasing_time_names_file_column_and_row(tmp_path):
    path = tmp_path / "bad.csv"
    path.write_text("time,x\n0,1\n2,1\n1,1\n")
    with pytest.raises(InputError, match=r"bad\.csv.*'time' decreases in data row 3"):
        read_trace(path)


def test_nan_time_is_rejected(tmp_path):
    path = tmp_path / "bad.csv"
    path.write_text("time,x\n0,1\n,1\n")
    with pytest.raises(InputError, match=r"bad\.csv.*'time'"):
        read_trace(path)


def test_non_numeric_column_is_rejected(tmp_path):
    path = tmp_path / "bad.csv"
    path.write_text("time,mode\n0,idle\n1,run\n")
    with pytest.raises(InputError, match=r"bad\.csv.*'mode'"):
        read_trace(path)


def test_duplicate_csv_columns_are_rejected(tmp_path):
    path = tmp_path / "bad.csv"
    path.write_text("time,x,x\n0,1,2\n")
    with pytest.raises(InputError, match=r"bad\.csv.*duplicate.*'x'"):
        read_trace(path)


def test_missing_and_unreadable_files(tmp_path):
    with pytest.raises(InputError, match=r"nope\.parquet: no such file"):
        read_trace(tmp_path / "nope.parquet")
    garbage = tmp_path / "garbage.parquet"
    garbage.write_bytes(b"this is not parquet")
    with pytest.raises(InputError, match=r"garbage\.parquet: cannot read"):
        read_trace(garbage)
    with pytest.raises(InputError, match="unknown trace format"):
        read_trace(tmp_path / "trace.txt")


@pytest.mark.parametrize("key", ["", "a:b", "a\nb", " a"])
def test_bad_metadata_keys_are_refused(tmp_path, key):
    with pytest.raises(InputError):
        write_trace(pd.DataFrame({"time": [0.0]}), tmp_path / "t.csv", {key: "v"})


def test_writer_refuses_decreasing_time(tmp_path):
    with pytest.raises(InputError, match="decreases"):
        write_trace(pd.DataFrame({"time": [1.0, 0.0]}), tmp_path / "t.parquet")


def test_csv_with_bom_and_semicolons_reads_bit_exact(tmp_path):
    t = np.array([0.0, 0.1, 0.1, 1 / 3])
    y = np.array([1e-300, -2.5, np.pi, 12345.678901234567])
    rows = [f"{float(a)!r};{float(b)!r}".replace(".", ",") for a, b in zip(t, y)]
    path = tmp_path / "excel.csv"
    path.write_text("\ufefftime;motor.tau\r\n" + "\r\n".join(rows) + "\r\n", encoding="utf-8")
    table, meta = read_trace(path)
    assert meta == {}
    assert list(table.columns) == ["time", "motor.tau"]
    assert np.array_equal(table["time"], t) and np.array_equal(table["motor.tau"], y)
