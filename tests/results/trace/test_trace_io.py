"""Tests of heliostep.results.trace.files: the trace file format."""

from __future__ import annotations

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


@pytest.mark.parametrize("suffix", [".parquet", ".csv"])
def test_round_trip_values_metadata_and_duplicate_times(tmp_path, suffix):
    path = tmp_path / f"trace{suffix}"
    write_trace(_trace(), path, META)
    table, meta = read_trace(path)
    assert meta == META
    assert list(table.columns) == ["time", "motor.tau", "panel_angle_error"]
    expected = _trace()
    for column in expected.columns:
        # Bit-for-bit equal, NaN where NaN.
        np.testing.assert_array_equal(table[column].to_numpy(), expected[column].to_numpy())
        assert table[column].dtype == np.float64
    assert table["time"].tolist().count(1.0) == 2


@pytest.mark.parametrize("suffix", [".parquet", ".csv"])
def test_time_is_written_first_and_ints_become_floats(tmp_path, suffix):
    path = tmp_path / f"trace{suffix}"
    write_trace(pd.DataFrame({"b": [1, 2], "time": [0, 1]}), path)
    table, meta = read_trace(path)
    assert meta == {}
    assert list(table.columns) == ["time", "b"]
    assert table["b"].dtype == np.float64
    assert table["b"].tolist() == [1.0, 2.0]


def test_csv_layout_is_metadata_lines_then_header(tmp_path):
    path = tmp_path / "t.csv"
    write_trace(pd.DataFrame({"time": [0.0, 1.0, 1.0], "x": [0.5, 0.5, 2.0]}), path, {"complete": True})
    assert path.read_text().splitlines() == [
        "# complete: true",
        "time,x",
        "0,0.5",
        "1,0.5",
        "1,2",
    ]


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
    assert lines[0] == 'time,"a,""b"""'
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
    path.write_text("# complete: true\n#unit.x:m\n\ntime,x\n0,1\n1,2.5\n")
    table, meta = read_trace(path)
    assert meta == {"complete": "true", "unit.x": "m"}
    assert table["x"].tolist() == [1.0, 2.5]


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


def test_malformed_metadata_line(tmp_path):
    path = tmp_path / "bad.csv"
    path.write_text("# complete true\ntime,x\n0,1\n")
    with pytest.raises(InputError, match=r"bad\.csv: line 1"):
        read_trace(path)


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
    path.write_text("\ufeff# complete: true\r\ntime;motor.tau\r\n" + "\r\n".join(rows) + "\r\n", encoding="utf-8")
    table, meta = read_trace(path)
    assert meta == {"complete": "true"}
    assert list(table.columns) == ["time", "motor.tau"]
    assert np.array_equal(table["time"], t) and np.array_equal(table["motor.tau"], y)
