"""The installed ``heliostep`` command (:func:`heliostep.cli.console_main`) in a real process: its report, its
files whole and its exit status, on 10 s of the paper's case and on bad input."""

from __future__ import annotations

import json
import subprocess

import pyarrow.parquet as pq

from heliostep.paths import scenarios_dir
from heliostep_process import HELIOSTEP


def test_the_installed_command_exits_with_its_report_and_files_whole(tmp_path):
    command = [*HELIOSTEP, "run"]
    scenario = str(scenarios_dir() / "jan21-central.yaml")
    out = tmp_path / "run"
    done = subprocess.run(
        [*command, scenario, "--out", str(out), "--no-plots", "--set", "window.duration=10"],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert done.returncode == 0, done.stderr
    assert done.stdout.rstrip().splitlines()[-1].split()[:2] == ["wall", "time"]  # the report's last line
    summary = json.loads((out / "summary.json").read_text())
    assert summary["complete"] is True and summary["duration_s"] == 10
    assert pq.read_metadata(out / "trace.parquet").num_rows == summary["rows"] > 0  # the trace whole
    bad = subprocess.run(
        [*command, scenario, "--out", str(tmp_path / "bad"), "--set", "window.duration=-1"],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert bad.returncode == 2 and "window.duration" in bad.stderr
