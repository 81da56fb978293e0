"""A sweep's results table belongs to its sweep: another sweep into the folder is refused unless
``--replace``, the same sweep resumes it; on a real two-worker local cluster (``heliostep sweep --scheduler``)."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml
from distributed import Client

from heliostep import cli
from heliostep.errors import InputError
from heliostep.paths import scenarios_dir
from heliostep.sweep import read_results, run_sweep
from loopback_cluster import loopback_client

BASE = scenarios_dir() / "jan21-central.yaml"
SHORT_WINDOW = {"window.duration": 20, "output.interval": 0.5}


@pytest.fixture(scope="module")
def address(fmu_paths):
    with loopback_client() as client:
        yield client.scheduler.address


def write_sweep(folder: Path, name: str, days: list[int]) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / f"{name}.yaml"
    data = {"base": str(BASE), "overrides": SHORT_WINDOW, "axes": {"day_of_year": days}}
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def sweep(sweep_file: Path, out: Path, address: str, *extra: str) -> int:
    return cli.main(["sweep", str(sweep_file), "--out", str(out), "--scheduler", address, "--no-plots", *extra])


def finished(results: Path) -> dict:
    table = read_results(results)
    return dict(zip(table["case_id"], table["finished_at"]))


def test_another_sweep_into_the_folder_is_refused_naming_both_and_replace_lets_it(address, tmp_path, capsys):
    first = write_sweep(tmp_path / "a", "days", [21, 172])
    other = write_sweep(tmp_path / "b", "days", [111])  # the same name, another file
    out = tmp_path / "out"
    results = out / "results.parquet"
    assert sweep(first, out, address) == 0
    rows = finished(results)
    assert len(rows) == 2
    capsys.readouterr()

    assert sweep(other, out, address) == 2
    err = capsys.readouterr().err
    assert f"{results}: holds 2 finished case(s) of sweep 'days' ({first.resolve()})" in err, err
    assert f"not of this sweep 'days' ({other.resolve()})" in err and "--replace" in err, err
    assert finished(results) == rows  # not a row lost

    assert sweep(first, out, address) == 0  # the same sweep resumes: nothing run again, nothing lost
    assert "0 run now, 2 already done" in capsys.readouterr().out
    assert finished(results) == rows

    assert sweep(other, out, address, "--replace") == 0
    assert list(read_results(results)["day_of_year"]) == [111]
    assert read_results(results).attrs["sweep"]["file"] == str(other.resolve())


def test_the_api_refuses_another_sweeps_table_before_any_case_runs(address, tmp_path):
    results = tmp_path / "results.parquet"
    with Client(address) as client:
        run_sweep(write_sweep(tmp_path, "first", [21]), results, client=client)
        rows = finished(results)
        with pytest.raises(InputError, match=r"holds 1 finished case\(s\) of sweep 'first'.*this sweep 'second'"):
            run_sweep(write_sweep(tmp_path, "second", [172]), results, client=client)
        assert finished(results) == rows
        replaced = run_sweep(write_sweep(tmp_path, "second", [172]), results, client=client, replace=True)
    assert (replaced.executed, len(replaced.table)) == (1, 1)


def test_a_new_table_names_its_sweep_before_its_first_row_is_merged(address, tmp_path):
    """The table is written empty at the start: a sweep killed before its first merge leaves part files
    whose sweep the table still names."""
    results = tmp_path / "results.parquet"
    seen = []

    class Stop(Exception):
        pass

    def look_then_stop(row):
        seen.append(read_results(results).attrs["sweep"].get("name"))
        raise Stop

    with Client(address) as client:
        with pytest.raises(Stop):
            run_sweep(write_sweep(tmp_path, "first", [21, 172]), results, client=client, on_result=look_then_stop)
        assert seen == ["first"]
        with pytest.raises(InputError, match="of sweep 'first'"):
            run_sweep(write_sweep(tmp_path, "second", [111]), results, client=client)
