"""Ctrl+C during ``heliostep sweep`` on its own local cluster: one line on stderr, exit 130, the finished cases kept.

The sweep runs as the installed command does, in its own process group (a terminal's foreground job), with a
real two-worker loopback cluster; SIGINT goes to the whole group, as a terminal sends it: the command, the
cluster's worker processes and their supervised runs.
"""

from __future__ import annotations

import os
import re
import signal
import subprocess
import time
from pathlib import Path

import pytest
import yaml

from heliostep.paths import scenarios_dir
from heliostep.sweep import read_results
from heliostep_process import HELIOSTEP

DAYS = [21, 60, 111, 172, 200, 264, 300, 350]
#: Bound on each wait for a state of the sweep [s] (cluster start and a 20 s window's case on a busy machine).
WAIT = 300.0


def start_sweep(tmp_path: Path) -> tuple[subprocess.Popen, Path]:
    sweep = tmp_path / "days.yaml"
    sweep.write_text(
        yaml.safe_dump(
            {
                "base": str(scenarios_dir() / "jan21-central.yaml"),
                "overrides": {"window.duration": 20, "output.interval": 0.5},
                "axes": {"day_of_year": DAYS},
            }
        )
    )
    out = tmp_path / "out"
    process = subprocess.Popen(
        [*HELIOSTEP, "sweep", str(sweep), "--out", str(out), "--workers", "2", "--no-plots"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
    )
    return process, out / "results.parquet"


def wait_for(process: subprocess.Popen, state, what: str) -> None:
    deadline = time.monotonic() + WAIT
    while not state():
        if process.poll() is not None:
            pytest.fail(f"the sweep ended before {what}: {process.communicate()}")
        if time.monotonic() > deadline:
            os.killpg(process.pid, signal.SIGKILL)
            pytest.fail(f"no {what} within {WAIT:g} s")
        time.sleep(0.05)


def interrupted(process: subprocess.Popen) -> str:
    """SIGINT to the sweep's process group; its stderr once it has ended (exit 130 checked)."""
    os.killpg(process.pid, signal.SIGINT)
    _, stderr = process.communicate(timeout=WAIT)
    assert process.returncode == 130, stderr
    return stderr


def assert_only_the_stop_line(stderr: str, results: Path) -> None:
    for text in ("Traceback", "KeyboardInterrupt", "AssertionError", "distributed."):
        assert text not in stderr, stderr
    lines = stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("heliostep sweep: stopped by SIGINT; "), stderr
    assert f"recorded in {results}; rerun the same command to run the rest" in lines[0], stderr


def test_ctrl_c_while_cases_run_prints_one_line_and_keeps_the_finished_cases(tmp_path, fmu_paths):
    process, results = start_sweep(tmp_path)
    parts = results.with_name(results.name + ".parts")
    wait_for(process, lambda: parts.is_dir() and any(parts.glob("*.arrow")), "finished case")
    stderr = interrupted(process)
    assert_only_the_stop_line(stderr, results)
    kept = read_results(results)
    assert 1 <= len(kept) < len(DAYS) and (kept["status"] == "ok").all()
    assert f"{len(kept)} case(s) recorded" in stderr


def test_ctrl_c_while_the_cluster_starts_prints_one_line(tmp_path, fmu_paths):
    """The table is written (empty) just before the local cluster starts: the signal comes while its
    processes start or just after, and is taken by the command alone either way."""
    process, results = start_sweep(tmp_path)
    wait_for(process, results.exists, "results table")
    stderr = interrupted(process)
    assert_only_the_stop_line(stderr, results)


def test_a_sweep_killed_outright_is_taken_up_again_by_the_same_command(tmp_path, fmu_paths):
    """SIGKILL leaves the table marked as being written in the manifest (no digest yet): the same sweep
    takes it up again, keeps the finished cases and runs the rest."""
    process, results = start_sweep(tmp_path)
    parts = results.with_name(results.name + ".parts")
    wait_for(process, lambda: parts.is_dir() and any(parts.glob("*.arrow")), "finished case")
    os.killpg(process.pid, signal.SIGKILL)
    process.communicate(timeout=WAIT)
    again, _ = start_sweep(tmp_path)
    stdout, stderr = again.communicate(timeout=WAIT)
    assert again.returncode == 0, stderr
    done = re.search(r"(\d+) run now, (\d+) already done", stdout)
    assert done and int(done.group(2)) >= 1 and int(done.group(1)) + int(done.group(2)) == len(DAYS), stdout
    table = read_results(results)
    assert sorted(table["day_of_year"]) == DAYS and (table["status"] == "ok").all()
