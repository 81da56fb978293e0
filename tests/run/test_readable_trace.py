"""A run's ``trace.csv`` opens anywhere: one header row (every column's unit in its name, angles in degrees),
a local time column in the site's zone beside the seconds, and the metadata in the ``metadata.json`` beside
it; ``RunResult.to_pandas(index="local_time")`` gives the trace on a time-zone-aware index, as pvlib's are."""

from __future__ import annotations

import csv
import json

import numpy as np
import pandas as pd
import pytest

from heliostep.paths import scenarios_dir
from heliostep.results.trace.files import read_trace, read_trace_metadata
from heliostep.run import RunOptions, run_scenario


@pytest.fixture(scope="module")
def written(fmu_paths, tmp_path_factory):
    run = run_scenario(
        scenarios_dir() / "jan21-central.yaml", RunOptions(stream=False), overrides=["window.duration=10"]
    )
    out = tmp_path_factory.mktemp("readable")
    run.write(out, plots=False, csv=True)
    return run, out


def test_the_trace_csv_reads_with_pandas_and_the_csv_module_as_it_is(written):
    run, out = written
    with open(out / "trace.csv", newline="", encoding="utf-8") as fh:
        header = next(csv.reader(fh))
    table = pd.read_csv(out / "trace.csv")
    assert list(table.columns) == header and len(table) == len(run.trace)
    assert header[:2] == ["time [s]", "local_time"]
    names = {c: c.rsplit(" [", 1)[0] for c in header if c != "local_time"}
    assert all(c.endswith("]") for c in names), header  # every column's unit in its name
    assert set(names.values()) == set(run.trace.columns)
    assert "mechanics.theta_p [deg]" in header  # angles in degrees, exactly np.degrees's
    np.testing.assert_array_equal(table["mechanics.theta_p [deg]"], np.degrees(run.trace["mechanics.theta_p"]))
    np.testing.assert_array_equal(table["motor.tau [N.m]"], run.trace["motor.tau"])
    np.testing.assert_array_equal(table["time [s]"], run.trace["time"])


def test_the_local_time_is_the_windows_start_plus_the_seconds_in_the_sites_zone(written):
    run, out = written
    table = pd.read_csv(out / "trace.csv")
    zone = run.scenario.site.timezone
    stamps = pd.to_datetime(table["local_time"], utc=True).dt.tz_convert(zone)
    start = pd.Timestamp(run.metadata["window_start"]).tz_convert(zone)
    assert start == pd.Timestamp("2025-01-21T10:00:00", tz=zone)
    expected = [start + pd.Timedelta(microseconds=round(t * 1e6)) for t in table["time [s]"]]
    assert stamps.tolist() == expected
    assert table["local_time"].iloc[0] == "2025-01-21T10:00:00.000000+01:00"


def test_metadata_json_holds_the_traces_metadata(written):
    run, out = written
    record = json.loads((out / "metadata.json").read_text())
    assert record["trace"] == run.trace_metadata() == read_trace_metadata(out / "trace.parquet")
    assert record["trace"]["unit.mechanics.theta_p"] == "rad" and record["trace"]["complete"] == "true"
    assert "# " not in (out / "trace.csv").read_text(encoding="utf-8")[:4096]
    assert read_trace(out / "trace.csv")[1] == record["trace"]  # heliostep's reader finds it there


def test_to_pandas_indexes_by_the_local_time_on_request(written):
    run, _ = written
    plain = run.to_pandas()
    assert isinstance(plain.index, pd.RangeIndex) and plain["time"].tolist() == run.trace["time"].tolist()
    indexed = run.to_pandas(index="local_time")
    assert isinstance(indexed.index, pd.DatetimeIndex) and indexed.index.name == "local_time"
    assert str(indexed.index.tz) == run.scenario.site.timezone == "Europe/Rome"
    start = pd.Timestamp("2025-01-21T10:00:00", tz="Europe/Rome")
    assert indexed.index[0] == start and indexed.index[-1] == start + pd.Timedelta(seconds=10)
    seconds = (indexed.index - start).total_seconds().to_numpy()
    np.testing.assert_allclose(seconds, indexed["time"], rtol=0, atol=1e-9)  # to the nanosecond
    pd.testing.assert_frame_equal(indexed.reset_index(drop=True), plain, check_exact=True)
    with pytest.raises(ValueError, match="expected None or 'local_time'"):
        run.to_pandas(index="time")
