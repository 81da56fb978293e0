"""The estimate before the work (issue 22, item 1): a run's steps, rows, memory and disk from its
scenario alone, checked against what the shipped scenarios take; a run over the budget is exit 2
naming the key, before anything is computed; input preparation honours a stop request.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import time
from pathlib import Path

import pytest

from heliostep.cli import main
from heliostep.paths import scenarios_dir
from heliostep.run import HELD_TRACE_MAX_DURATION, run_scenario
from heliostep.run.estimate import estimate_run
from heliostep.scenario import load_scenario
from heliostep_process import HELIOSTEP

SHORT_SCENARIOS = [
    "jan21-central",
    "jan21-paper-literal",
    "jan21-ideal-current",
    "jan21-small-angle",
    "jan21-weak-motor",
]


@pytest.mark.parametrize("name", [*SHORT_SCENARIOS[::2], "jan21-day"])  # the paper's, ideal current, weak motor
def test_the_estimate_gives_the_rows_and_steps_a_run_takes(name, fmu_paths):
    """Rows within 2 %, steps within 2 % (or one step) of the run's own, counted on its trace."""
    scenario = load_scenario(name)
    estimate = estimate_run(scenario, HELD_TRACE_MAX_DURATION)
    run = run_scenario(scenario)
    steps = len(run.inputs.schedule)
    assert estimate.rows == pytest.approx(run.trace_rows, rel=0.02)
    assert abs(estimate.steps - steps) <= max(1.0, 0.02 * steps)
    assert estimate.events == pytest.approx(steps, abs=max(1.0, 0.02 * steps))  # a step is an event
    assert estimate.held is (run.trace_file is None)


@pytest.mark.parametrize("name", ["jan21-central", "jan21-day"])
def test_the_estimate_bounds_memory_and_disk_within_a_factor_two(name, tmp_path, fmu_paths):
    """Measured in a process of its own: its peak resident memory (Linux's VmHWM, its own: not
    the pytest parent's, which ``ru_maxrss`` would carry across fork and exec) and the bytes of
    its files."""
    out = tmp_path / "out"
    done = subprocess.run([*HELIOSTEP, "run", name, "--out", str(out)], capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    peak = json.loads((out / "metadata.json").read_text())["statistics"]["peak_rss_mb_simulating"] * 1e6
    disk = sum(p.stat().st_size for p in out.iterdir())
    estimate = estimate_run(load_scenario(name), HELD_TRACE_MAX_DURATION)
    assert peak <= estimate.memory_bytes <= 2 * peak
    assert disk <= estimate.disk_bytes <= 2 * disk


@pytest.mark.parametrize(
    "key, value, named",
    [
        ("output.step_interval", "1e-9", "output.step_interval = 1e-09"),
        ("sequencer.step_angle", "1e-9", "sequencer.step_angle = 1e-09"),
        ("transmission.pinion_radius", "1e-10", "transmission.pinion_radius = 1e-10"),
        ("transmission.pinion_radius", "1e-15", "transmission.pinion_radius = 1e-15"),
        ("output.interval", "1e-300", "output.interval = 1e-300"),
        ("window.duration", "1e9", "window.duration"),
    ],
)
def test_a_run_over_the_budget_is_refused_before_any_work_naming_the_key(key, value, named, tmp_path):
    out = tmp_path / "out"
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    done = subprocess.run(
        [*HELIOSTEP, "run", "jan21-central", "--out", str(out), "--set", f"{key}={value}"],
        capture_output=True,
        text=True,
        timeout=120,  # before: 24 GB and the kernel's OOM killer, or minutes deaf to signals
        env={**os.environ, "TMPDIR": str(tmp)},
    )
    assert done.returncode == 2, done.stderr
    assert named in done.stderr and "makes the run too large" in done.stderr and "budget" in done.stderr
    assert "Traceback" not in done.stderr and len(done.stderr.strip().splitlines()) == 1
    assert not out.exists() and list(tmp.iterdir()) == []  # nothing made: no FMU unpacked, no folder


def test_the_budget_is_settable_by_key_and_option(tmp_path, capsys, fmu_paths):
    scenario = str(scenarios_dir() / "jan21-central.yaml")
    assert main(["run", scenario, "--out", str(tmp_path / "a"), "--max-memory", "0.1"]) == 2
    err = capsys.readouterr().err
    assert "over the memory budget of 0.1 GB" in err and "budget.memory_gb" in err
    assert main(["run", scenario, "--out", str(tmp_path / "b"), "--set", "budget.disk_gb=0.001"]) == 2
    assert "over the disk budget of 0.001 GB" in capsys.readouterr().err
    # raised, a run refused by default goes ahead: 2 ms rows over 5 minutes, 150,000 rows
    args = ["--set", "output.interval=0.002", "--max-memory", "8", "--no-plots", "--no-csv"]
    estimate = estimate_run(load_scenario(scenario, ["output.interval=0.002"]), HELD_TRACE_MAX_DURATION)
    assert estimate.rows == pytest.approx(300 / 0.002 + 16 * 101, rel=0.01)  # the regular grid, the steps' fine grids
    assert main(["run", scenario, "--out", str(tmp_path / "c"), *args, "--max-disk", "0.01"]) == 2  # its disk
    assert main(["run", scenario, "--out", str(tmp_path / "c"), *args]) == 0
    assert json.loads((tmp_path / "c" / "summary.json").read_text())["rows"] == pytest.approx(estimate.rows, rel=0.02)


def _cpu_seconds(pid: int) -> float:
    """CPU time [s] process ``pid`` has used (user + system; proc(5), /proc/PID/stat fields 14 and 15)."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def _wait_for_cpu_seconds(pid: int, seconds: float, deadline: float) -> None:
    """Wait until process ``pid`` has used ``seconds`` more of CPU time [s]: a phase reached by the
    process's own work, not by the wall clock, which a loaded machine stretches."""
    start = _cpu_seconds(pid)
    while time.monotonic() < deadline:
        if _cpu_seconds(pid) - start >= seconds:
            return
        time.sleep(0.02)
    raise AssertionError(f"process {pid} used under {seconds} s of CPU before the deadline")


def test_a_stop_request_while_the_inputs_are_prepared_is_honoured_at_once(tmp_path, fmu_paths):
    """A million steps to schedule (a step angle 1000 times finer, within the budget): SIGTERM
    two seconds into the preparation ends the command within seconds, exit 143, only its stopped records left."""
    out = tmp_path / "out"
    process = subprocess.Popen(
        [*HELIOSTEP, "run", "jan21-day", "--out", str(out), "--set", "sequencer.step_angle=0.0018"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    deadline = time.monotonic() + 60
    while not (out / ".heliostep-lock").exists():  # the folder is held: the run is being prepared
        assert process.poll() is None and time.monotonic() < deadline, process.communicate()
        time.sleep(0.01)
    _wait_for_cpu_seconds(process.pid, 2.0, deadline)  # two seconds of its own work, however loaded the machine
    assert process.poll() is None
    process.send_signal(signal.SIGTERM)
    sent = time.monotonic()
    _, stderr = process.communicate(timeout=30)
    assert time.monotonic() - sent < 10  # the schedule loop looks at the request every 1024 steps
    assert process.returncode == 143 and "while preparing the inputs" in stderr and "Traceback" not in stderr, stderr
    # nothing computed is written, only the records of a run stopped before simulating (complete: false)
    assert sorted(p.name for p in Path(out).iterdir()) == [".heliostep-manifest.json", "metadata.json", "summary.json"]
    summary = json.loads((out / "summary.json").read_text())
    assert summary["complete"] is False and summary["stage"] == "preparing_inputs"


def test_a_loops_rows_count_in_memory_whatever_the_window():
    """A closed loop keeps its output rows in memory until its steps are decided: a week's are held, and
    the memory grows by them (their number times the trace's columns)."""
    week = ("window.duration=604800", "output.step_detail=0")
    open_loop = estimate_run(load_scenario("jan21-central", week), HELD_TRACE_MAX_DURATION)
    closed = estimate_run(load_scenario("jan21-central", (*week, "tracking.mode=closed_loop")), HELD_TRACE_MAX_DURATION)
    assert not open_loop.held and closed.held and closed.rows == open_loop.rows
    assert closed.memory_bytes > open_loop.memory_bytes + closed.rows * 10 * 8  # at least ten 8-byte columns a row
