"""Supervised runs: an FMU that crashes, exits or hangs ends the run with exit 1, named with its FMI
call, the trace and figures so far kept and marked, nothing left in TMPDIR and no fault dump of the
child's on stderr; the child forked, or started by multiprocessing's fork server (a Dask worker's way).

The misbehaving FMU is ``Faulty`` (``tests/data/mini/faulty.c``, built with gcc), an extra FMU of
the paper's scenario: der(x) = 1 until ``t_fault``, then in fmi2GetDerivatives a write through a
null pointer, ``abort()``, ``exit(0)``, ``exit(3)`` or an endless loop. Real processes, signals
and CVODE; no mocks.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import signal
import struct
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from heliostep.results.trace.files import read_trace
from heliostep.run import RunFailed, RunOptions, run_scenario
from third_party_fmu import build_mini_fmu

CLI = "from heliostep.cli import console_main; console_main()"
T_FAULT = 200.0  # [s] of the 300 s window: well after the first rows are handed over
NOT_OURS = "notes.txt"


@pytest.fixture(scope="module")
def faulty_fmu(tmp_path_factory) -> Path:
    return build_mini_fmu("Faulty", tmp_path_factory.mktemp("faulty"))


def _scenario(folder: Path, fmu: Path, fault: int, t_fault: float = T_FAULT) -> Path:
    """The paper's 5-minute case (jan21-central) with the Faulty FMU beside its motor and mechanics."""
    path = folder / f"faulty-{fault}.yaml"
    path.write_text(
        f"name: faulty-{fault}\n"
        "site: {latitude: 40.0, longitude: 14.25, altitude: 0.0, timezone: Europe/Rome}\n"
        'window: {date: 2025-01-21, start: "10:00", duration: 300}\n'
        "plant: {orientation: NS, tube_height: 3.0}\n"
        "mirror: {distance: 0.0, axis: secondary}\n"
        f"fmus: {{motor: StepperMotor, mechanics: PanelMechanics, faulty: {fmu}}}\n"
        f"parameters: {{faulty: {{fault: {fault}, t_fault: {t_fault}}}}}\n"
        "sequencer: {mode: one-phase-on, current: 5.5, step_angle: 1.8}\n"
        "solver: {rtol: 1.0e-6, max_step: 1.0}\n"  # CVODE's steps at most 1 s: see _rows_computed
        "output: {interval: 0.1, step_detail: 0.05, step_interval: 0.0005}\n"
    )
    return path


#: A supervising process whose child the fork server starts: run_scenario on the scenario ``argv[1]``.
SERVED = (
    "import sys; from heliostep.run import RunOptions, run_scenario\n"
    "run_scenario(sys.argv[1], RunOptions(supervise=True, keep_trace=False, start_method='forkserver'))\n"
)


@pytest.fixture
def private():
    """A TMPDIR of the test's own, with a short path: multiprocessing's fork server puts its socket there, and a
    Unix socket's path holds at most 107 bytes (a pytest tmp_path can be longer)."""
    folder = Path(tempfile.mkdtemp(prefix="hs-", dir="/tmp"))
    yield folder
    shutil.rmtree(folder, ignore_errors=True)


def _start(scenario: Path, out: Path, private_tmp: Path, *extra: str, start: str = "fork") -> subprocess.Popen:
    """``heliostep run`` in a subprocess with a TMPDIR of its own (its supervised child forked), or with
    ``start="forkserver"`` a process that runs the scenario with its child started by the fork server."""
    private_tmp.mkdir(exist_ok=True)
    env = {**os.environ, "TMPDIR": str(private_tmp)}
    command = [sys.executable, "-c", CLI, "run", str(scenario), "--out", str(out), "--no-plots", *extra]
    if start == "forkserver":
        command = [sys.executable, "-c", SERVED, str(scenario)]
    return subprocess.Popen(command, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


@pytest.fixture(scope="module")
def complete_trace(faulty_fmu, tmp_path_factory) -> pd.DataFrame:
    """The same scenario without a fault, simulated in-process (unsupervised): the rows a faulty
    run's trace must hold, up to where it stopped."""
    folder = tmp_path_factory.mktemp("complete")
    return run_scenario(_scenario(folder, faulty_fmu, 0), RunOptions(supervise=False)).trace


def _rows_computed(complete: pd.DataFrame, fault_at: float) -> int:
    """The trace rows a run computed before its FMU failed in an evaluation at ``fault_at`` [s]: at
    least those up to the start of CVODE's step then (steps of at most 1 s: solver.max_step)."""
    return int((complete["time"] <= fault_at - 1.0).sum())


FAULTS = {  # fault code: (how the message says the process ended, reason)
    1: ("was killed by SIGSEGV", "fmu-crashed"),
    2: ("was killed by SIGABRT", "fmu-crashed"),
    3: ("exited with status 0 without finishing", "fmu-crashed"),
    4: ("exited with status 3 without finishing", "fmu-crashed"),
    5: ("the FMU hangs: no FMI call begun for 3 s (the watchdog)", "fmu-hung"),
}


@pytest.mark.parametrize("fault", sorted(FAULTS))
def test_a_crashing_exiting_or_hanging_fmu_fails_the_run_named_with_its_trace_so_far(
    fault, faulty_fmu, complete_trace, tmp_path, fmu_paths, private
):
    out = tmp_path / "out"
    out.mkdir()
    (out / NOT_OURS).write_text("the user's")
    process = _start(_scenario(tmp_path, faulty_fmu, fault), out, private, "--watchdog", "3")
    _, stderr = process.communicate(timeout=120)
    ended, reason = FAULTS[fault]
    assert process.returncode == 1, stderr[-3000:]  # never 0, 3, 134 or 139
    assert "Traceback" not in stderr and "Fatal Python error" not in stderr  # the child's crash: no dump
    message = re.search(r"heliostep run: error: (.*)", stderr)
    assert message, stderr[-3000:]
    assert ended in message.group(1)
    assert "in fmi2GetDerivatives of FMU instance 'faulty' (model Faulty) at t = " in message.group(1)
    called_at = float(re.search(r"\(model Faulty\) at t = ([0-9.e+-]+) s", message.group(1)).group(1))
    assert T_FAULT <= called_at < T_FAULT + 5.0  # the first evaluation past t_fault (a step of CVODE's)

    summary = json.loads((out / "summary.json").read_text())
    assert summary["complete"] is False and summary["reason"] == reason
    assert ended in summary["error"]
    trace, meta = read_trace(out / "trace.parquet")
    assert meta["complete"] == "false" and meta["reason"] == reason
    reached = float(trace["time"].iloc[-1])
    assert summary["time_reached_s"] == pytest.approx(called_at)  # the FMU's last time
    # every row computed before the fault is kept (those sent, and those the child's journal held)
    assert _rows_computed(complete_trace, called_at) <= len(trace) and reached < T_FAULT
    # first principles: der(x) = 1 from x(0) = 0, so x is the time
    np.testing.assert_allclose(trace["faulty.x"], trace["time"], rtol=0, atol=1e-6)
    # and the rows are those of the run without a fault, up to where it stopped
    expected = complete_trace.iloc[: len(trace)]
    for column in ("time", "motor.i_a", "motor.tau", "mechanics.theta_p", "faulty.x"):
        np.testing.assert_array_equal(trace[column].to_numpy(), expected[column].to_numpy())
    assert (out / NOT_OURS).read_text() == "the user's"
    assert not [p for p in out.iterdir() if p.name.startswith(".heliostep-tmp-")]
    assert sorted(p.name for p in private.iterdir()) == []  # no unpacked FMU, no partial trace


EARLY = 5.0  # [s] of the 300 s window: before the child's first message


@pytest.mark.parametrize("fault", [1, 2, 3, 4])
def test_a_crash_before_the_childs_first_message_keeps_every_row_and_the_fmus_time(
    fault, faulty_fmu, complete_trace, tmp_path, fmu_paths, private
):
    out = tmp_path / "out"
    process = _start(_scenario(tmp_path, faulty_fmu, fault, t_fault=EARLY), out, private)
    _, stderr = process.communicate(timeout=120)
    assert process.returncode == 1, stderr[-3000:]
    assert "Traceback" not in stderr
    ended, reason = FAULTS[fault]
    summary = json.loads((out / "summary.json").read_text())
    assert summary["complete"] is False and summary["reason"] == reason and ended in summary["error"]
    assert EARLY <= summary["time_reached_s"] < EARLY + 1.0  # the FMU's time in the failing call (max_step 1 s)
    assert f"(model Faulty) at t = {summary['time_reached_s']:.9g} s" in summary["error"]
    trace, meta = read_trace(out / "trace.parquet")
    assert meta["complete"] == "false" and meta["reason"] == reason
    assert _rows_computed(complete_trace, summary["time_reached_s"]) <= len(trace) and trace["time"].iloc[-1] < EARLY
    expected = complete_trace.iloc[: len(trace)]
    for column in ("time", "motor.i_a", "mechanics.theta_p", "faulty.x"):
        np.testing.assert_array_equal(trace[column].to_numpy(), expected[column].to_numpy())
    assert summary["rows"] == len(trace) and summary["figures_from"] == "solution"
    assert f"the trace keeps the rows up to t = {trace['time'].iloc[-1]:.9g} s" in summary["error"]
    assert sorted(p.name for p in private.iterdir()) == []


@pytest.mark.parametrize("fault", [1, 5])
def test_a_crash_or_hang_in_a_child_of_the_fork_server_fails_the_run_with_its_figures_so_far(
    fault, faulty_fmu, complete_trace, tmp_path, fmu_paths, capfd
):
    """A Dask worker's way: the child started by multiprocessing's fork server; the run fails named,
    its figures those of the rows the child sent (the steps before the fault judged), no fault dump."""
    scenario = _scenario(tmp_path, faulty_fmu, fault)
    with pytest.raises(RunFailed) as failure:
        run_scenario(scenario, RunOptions(supervise=True, watchdog=3.0, keep_trace=False, start_method="forkserver"))
    result = failure.value.result
    ended, reason = FAULTS[fault]
    assert result.reason == reason and ended in str(failure.value)
    assert "in fmi2GetDerivatives of FMU instance 'faulty' (model Faulty)" in str(failure.value)
    figures = result.metadata["solution_figures"]
    assert 0 < figures["end_time_s"] < T_FAULT and figures["solution_rows"] > 1000
    commanded = int(np.sum(np.asarray(result.metadata["drive"]["step_times"]) <= figures["end_time_s"]))
    assert 0 < len(figures["step_outcomes"]) <= commanded
    assert "Fatal Python error" not in capfd.readouterr().err


def test_ctrl_c_stops_a_run_whose_fmu_hangs_and_keeps_its_trace(
    faulty_fmu, complete_trace, tmp_path, fmu_paths, private
):
    out = tmp_path / "out"
    process = _start(_scenario(tmp_path, faulty_fmu, 5, t_fault=150.0), out, private)  # the default watchdog: 60 s
    _wait_until_hung(private, process, 150.0)  # the FMU loops inside fmi2GetDerivatives
    signalled = time.monotonic()
    process.send_signal(signal.SIGINT)
    _, stderr = process.communicate(timeout=60)
    assert time.monotonic() - signalled < 10.0
    assert process.returncode == 130, stderr[-3000:]
    assert "Traceback" not in stderr
    assert "stopped by SIGINT" in stderr
    summary = json.loads((out / "summary.json").read_text())
    assert summary["complete"] is False and summary["reason"] == "interrupted"
    stuck = "did not stop within 1 s in fmi2GetDerivatives of FMU instance 'faulty' (model Faulty) at t = 15"
    assert stuck in summary["error"]
    trace, _ = read_trace(out / "trace.parquet")
    # every row computed before the FMU hung is kept; it hung at the first evaluation past t = 150 s
    assert _rows_computed(complete_trace, 150.0) <= len(trace) and trace["time"].iloc[-1] < 150.0
    np.testing.assert_array_equal(trace["time"].to_numpy(), complete_trace["time"].to_numpy()[: len(trace)])
    assert sorted(p.name for p in private.iterdir()) == []


@pytest.mark.parametrize("start", ["fork", "forkserver"])
def test_supervised_and_in_process_runs_give_the_same_trace_and_figures_bit_for_bit(start, fmu_paths, tmp_path):
    from heliostep.paths import scenarios_dir

    scenario = scenarios_dir() / "jan21-central.yaml"
    overrides = ("window.duration=60",)
    inside = run_scenario(scenario, RunOptions(supervise=False), overrides=overrides)
    supervised = run_scenario(scenario, RunOptions(supervise=True, start_method=start), overrides=overrides)
    assert list(inside.trace.columns) == list(supervised.trace.columns) and len(inside.trace) > 500
    for column in inside.trace.columns:
        np.testing.assert_array_equal(inside.trace[column].to_numpy(), supervised.trace[column].to_numpy())
    assert json.dumps(inside.summary, sort_keys=True, default=str) == json.dumps(
        supervised.summary, sort_keys=True, default=str
    )
    assert inside.metadata["solution_figures"] == supervised.metadata["solution_figures"]


def test_a_watchdog_that_is_not_positive_is_bad_input(tmp_path, fmu_paths):
    command = [sys.executable, "-c", CLI, "run", "jan21-central", "--watchdog", "0", "--no-plots"]
    result = subprocess.run(command, capture_output=True, text=True, timeout=120, cwd=tmp_path)
    assert result.returncode == 2, result.stderr[-3000:]
    assert "argument --watchdog: 0 s; expected a positive number of seconds" in result.stderr


def _wait_until_hung(private: Path, process: subprocess.Popen, t_fault: float) -> None:
    """Until the child's call record (in its supervisor's TMPDIR ``private``) says it is inside the
    looping fmi2GetDerivatives past ``t_fault`` [s]."""
    from heliostep.cosim.watch import FUNCTIONS, LAYOUT

    deadline = time.monotonic() + 120
    while True:
        assert process.poll() is None, process.communicate()
        assert time.monotonic() < deadline, "the FMU did not reach its fault"
        for record in private.glob("heliostep-child-*/calls"):
            try:
                _, function, _, _, at = struct.unpack(LAYOUT, record.read_bytes())
            except (OSError, struct.error):
                continue
            if FUNCTIONS[function] == "fmi2GetDerivatives" and at >= t_fault:
                time.sleep(0.2)  # (the record is written before the call: the child is in it by now)
                return
        time.sleep(0.05)


def _children(pid: int) -> list[int]:
    """The processes whose parent is ``pid`` (from /proc)."""
    found = []
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except OSError:  # ended meanwhile
            continue
        if int(fields[1]) == pid:
            found.append(int(stat.parent.name))
    return found


def _alive(pid: int) -> bool:
    """True while ``pid`` runs (a zombie, dead but not yet reaped by whoever adopted it, is not alive)."""
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] != "Z"
    except OSError:
        return False


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="needs Linux's /proc to find the child")
@pytest.mark.parametrize("start", ["fork", "forkserver"])
def test_a_hung_fmus_process_does_not_outlive_a_sigkilled_supervisor(start, faulty_fmu, tmp_path, fmu_paths, private):
    out = tmp_path / "out"
    process = _start(_scenario(tmp_path, faulty_fmu, 5, t_fault=20.0), out, private, start=start)  # watchdog 60 s
    _wait_until_hung(private, process, 20.0)
    children = _children(process.pid)
    if start == "forkserver":  # the supervisor's children: the fork server (the simulation its child), a tracker
        served = [grandchild for helper in children for grandchild in _children(helper)]
        server = next(helper for helper in children if _children(helper))
        assert len(served) == 1, (children, served)
        child = served[0]
    else:
        assert len(children) == 1, children
        child = children[0]
    assert _alive(child)
    process.kill()  # SIGKILL: the supervisor cannot clean up, nor kill its child itself
    process.communicate(timeout=30)
    deadline = time.monotonic() + 10
    while _alive(child):  # the child, looping in native code, is ended by the kernel (or its watcher)
        assert time.monotonic() < deadline, f"the hung child {child} outlived its supervisor"
        time.sleep(0.05)
    while start == "forkserver" and _alive(server):  # the fork server too, its supervisor's pipe closed
        assert time.monotonic() < deadline, f"the fork server {server} outlived its supervisor"
        time.sleep(0.05)


def _run_in_thread(scenario: Path, overrides: tuple[str, ...]):
    """``run_scenario(..., supervise=True)`` from a thread of its own, its child started by the fork
    server (this process runs two threads, as a Dask worker does)."""
    import threading

    results = []

    def run() -> None:
        options = RunOptions(supervise=True, start_method="forkserver")
        results.append(run_scenario(scenario, options, overrides=overrides))

    thread = threading.Thread(target=run)
    thread.start()
    thread.join()
    assert len(results) == 1
    return results[0]


def test_a_run_from_a_thread_started_by_the_fork_server_gives_the_same_bit_for_bit(fmu_paths):
    from heliostep.paths import scenarios_dir

    scenario, overrides = scenarios_dir() / "jan21-central.yaml", ("window.duration=60",)
    inside = run_scenario(scenario, RunOptions(supervise=False), overrides=overrides)
    served = _run_in_thread(scenario, overrides)
    for column in inside.trace.columns:
        np.testing.assert_array_equal(inside.trace[column].to_numpy(), served.trace[column].to_numpy())
    assert json.dumps(inside.summary, sort_keys=True, default=str) == json.dumps(
        served.summary, sort_keys=True, default=str
    )
    again = _run_in_thread(scenario, overrides)  # the fork server started once serves the next run too
    np.testing.assert_array_equal(inside.trace.to_numpy(), again.trace.to_numpy())


def test_an_unknown_start_method_is_bad_input(fmu_paths):
    from heliostep.errors import InputError
    from heliostep.paths import scenarios_dir

    with pytest.raises(InputError, match="start_method: 'spawn'; expected 'fork' or 'forkserver'"):
        run_scenario(
            scenarios_dir() / "jan21-central.yaml",
            RunOptions(supervise=True, start_method="spawn"),  # type: ignore[arg-type]
            overrides=("window.duration=1",),
        )
