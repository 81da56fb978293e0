"""``--out`` beginning with ``~`` means one place everywhere: the home folder, as a shell user expects (expanded
where the command reads --out); no writer expands ``~`` on its own (a literal folder named ``~`` stays one).

Real commands in subprocesses with a home folder of the test's, real files.
"""

from __future__ import annotations

import numpy as np

from heliostep.paths import scenarios_dir
from heliostep.results.trace.writer import TraceWriter
from heliostep_process import popen_heliostep

SCENARIO = str(scenarios_dir() / "jan21-central.yaml")


def _run(args: list[str], home, cwd) -> tuple[int, str]:
    process = popen_heliostep(args, env={"HOME": str(home)}, cwd=cwd)
    _, err = process.communicate(timeout=300)
    return process.returncode, err


def test_run_out_under_tilde_writes_every_file_in_the_home_folder(tmp_path):
    home, cwd = tmp_path / "home", tmp_path / "cwd"
    home.mkdir()
    cwd.mkdir()
    args = ["run", SCENARIO, "--set", "window.duration=20", "--no-plots", "--out", "~/result"]
    status, err = _run(args, home, cwd)
    assert status == 0, err[-2000:]
    assert {"trace.parquet", "summary.json", "metadata.json"} <= {p.name for p in (home / "result").iterdir()}
    assert list(cwd.iterdir()) == []  # no ./~ made


def test_geometry_out_tilde_alone_is_the_home_folder(tmp_path):
    home, cwd = tmp_path / "home", tmp_path / "cwd"
    home.mkdir()
    cwd.mkdir()
    status, err = _run(["geometry", "--date", "2025-06-21", "--step", "1800", "--out", "~"], home, cwd)
    assert status == 0, err[-2000:]
    assert (home / "two_axis_angles.csv").is_file()
    assert list(cwd.iterdir()) == []


def test_the_trace_writer_writes_a_literal_tilde_folder_not_the_home_folder(tmp_path, monkeypatch):
    home, cwd = tmp_path / "home", tmp_path / "cwd"
    home.mkdir()
    (cwd / "~").mkdir(parents=True)
    monkeypatch.setenv("HOME", str(home))
    monkeypatch.chdir(cwd)
    writer = TraceWriter("~/trace.parquet", ["time", "x"])
    writer.write({"time": np.array([0.0, 1.0]), "x": np.array([1.0, 2.0])})
    writer.close({})
    assert (cwd / "~" / "trace.parquet").is_file()
    assert list(home.iterdir()) == []
