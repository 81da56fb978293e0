"""``heliostep run`` / ``heliostep sweep`` stopped by real SIGINT and SIGTERM in a subprocess.

The run is a real co-simulation with the real FMUs (five days from sunrise on 21 January, tens of
seconds undisturbed); the signal comes 1 s after the trace stream's file appears in --out (made
once the inputs are prepared, as the simulation starts), so it lands mid-simulation (a signal
while the inputs are prepared ends the command there: tests/run/test_estimate.py).
"""

from __future__ import annotations

import glob
import hashlib
import json
import select
import signal
import subprocess
import time
from pathlib import Path

import pytest

from heliostep.paths import scenarios_dir
from heliostep.results.trace.files import read_trace
from heliostep_process import five_day_scenario, popen_heliostep

SCENARIOS = scenarios_dir()


def _fmu_dirs(tmp: Path) -> list[str]:
    return glob.glob(str(tmp / "heliostep-fmus-*"))


def _wait_for_fmus(
    tmp: Path, process: subprocess.Popen, timeout: float = 60.0, pattern: str = "heliostep-fmus-*"
) -> None:
    deadline = time.monotonic() + timeout
    while not glob.glob(str(tmp / pattern)):
        assert process.poll() is None, process.communicate()
        assert time.monotonic() < deadline, "the FMUs were not unpacked"
        time.sleep(0.05)


def _signal_twice(process: subprocess.Popen, sig, gap: float, status: int, out: Path) -> None:
    """Send ``sig`` twice, ``gap`` seconds apart: the run exits at once with ``status``, says so,
    prints no traceback and leaves no temporary file in ``out``."""
    process.send_signal(sig)
    time.sleep(gap)
    process.send_signal(sig)
    _, stderr = process.communicate(timeout=60)
    assert process.returncode == status, stderr
    assert "Traceback" not in stderr and f"stopped by {signal.Signals(sig).name} a second time" in stderr, stderr
    assert not [p for p in out.iterdir() if p.name.startswith(".heliostep-tmp-")]


@pytest.mark.parametrize("sig, status", [(signal.SIGINT, 130), (signal.SIGTERM, 143)])
def test_signal_stops_run_and_keeps_the_trace_so_far(sig, status, tmp_path, fmu_paths):
    out = tmp_path / "run"
    (out).mkdir()
    stale = b"stale figure of an earlier run"
    (out / "fig08_panel_angle_ref.png").write_bytes(stale)
    record = {"size": len(stale), "sha256": hashlib.sha256(stale).hexdigest()}  # as heliostep records its files
    (out / ".heliostep-manifest.json").write_text(json.dumps({"files": {"fig08_panel_angle_ref.png": record}}))
    (out / "notes.txt").write_text("not heliostep's")
    process = popen_heliostep(["run", str(five_day_scenario(tmp_path)), "--out", str(out)], tmp_path / "tmp")
    _wait_for_fmus(tmp_path / "tmp", process)  # unpacked to be checked
    _wait_for_fmus(tmp_path / "tmp", process, pattern="heliostep-child-*")  # the supervised child's: it simulates
    deadline = time.monotonic() + 60.0  # the stream's file is made once the inputs are prepared: simulating
    while not list(out.glob(".heliostep-tmp-*-trace.parquet")):
        assert process.poll() is None and time.monotonic() < deadline, "the trace is not being streamed"
        time.sleep(0.01)
    time.sleep(1.0)
    assert process.poll() is None, "the run ended before the signal"
    process.send_signal(sig)
    stdout, stderr = process.communicate(timeout=60)
    assert process.returncode == status, stderr
    assert "Traceback" not in stderr and "Traceback" not in stdout
    assert f"stopped by {signal.Signals(sig).name}" in stderr

    summary = json.loads((out / "summary.json").read_text())
    assert summary["complete"] is False and summary["reason"] == "interrupted"
    reached = summary["time_reached_s"]
    assert 0 < reached < 432000  # mid-window (five days from sunrise)
    metadata = json.loads((out / "metadata.json").read_text())
    assert metadata["complete"] is False and metadata["reason"] == "interrupted"
    assert metadata["time_reached_s"] == reached
    trace, meta = read_trace(out / "trace.parquet")
    assert meta["complete"] == "false" and meta["reason"] == "interrupted"
    assert float(meta["time_reached"]) == pytest.approx(reached)
    assert trace["time"].iloc[-1] == pytest.approx(reached)
    assert summary["rows"] == len(trace) > 10
    # the step in progress at the cut is not counted as missed
    assert summary["missed_steps"] == 0 and summary["steps_lost"] == 0, summary
    assert summary["steps_executed"] == summary["steps_commanded"] > 0
    assert metadata["roles"]["rotor_angle"] in trace
    # a long window (sunrise to sunset) gets no CSV by default; the earlier run's stale figure
    # is gone, the user's file stays, no temporary file is left
    assert not (out / "trace.csv").exists()
    assert not (out / "fig08_panel_angle_ref.png").exists()
    assert (out / "notes.txt").exists()
    assert not [p for p in out.iterdir() if p.name.startswith(".heliostep-tmp-")]
    assert _fmu_dirs(tmp_path / "tmp") == [], "FMU unpack folder left behind"


@pytest.mark.parametrize("sig, status", [(signal.SIGINT, 130), (signal.SIGTERM, 143)])
def test_signal_stops_sweep_cleanly_and_leaves_no_temporary_folder(sig, status, tmp_path, fmu_paths):
    sweep = tmp_path / "sweep.yaml"
    sweep.write_text(
        f"name: sigtest\nbase: {SCENARIOS / 'jan21-central.yaml'}\ncombine: product\n"
        f"axes:\n  day_of_year: {list(range(21, 61))}\n"  # far more than 6 s of cases
        "overrides:\n  window.duration: 7200\n  output.interval: 10.0\n"
    )
    out = tmp_path / "out"
    process = popen_heliostep(
        ["sweep", str(sweep), "--out", str(out), "--workers", "1", "--no-plots"], tmp_path / "tmp"
    )
    deadline = time.monotonic() + 120  # the cluster started and one case finished, however loaded the machine
    while not list(out.rglob("*.parquet")):
        assert process.poll() is None and time.monotonic() < deadline, process.communicate()
        time.sleep(0.05)
    process.send_signal(sig)
    _, stderr = process.communicate(timeout=60)
    assert process.returncode == status, stderr
    # no traceback of the command itself (under load, a Dask worker torn down mid-heartbeat may
    # still log one of its own: distributed's logging, in the worker process)
    assert "KeyboardInterrupt" not in stderr and "heliostep/cli" not in stderr, stderr
    assert f"stopped by {signal.Signals(sig).name}" in stderr and "rerun" in stderr
    # the workers, killed by the cluster's shutdown, leave nothing in TMPDIR: no Dask scratch
    # space, no FMU unpack folder, no trace stream of a case in progress
    assert list((tmp_path / "tmp").iterdir()) == []


def test_second_signal_while_writing_exits_at_once_and_leaves_no_temporary_file(tmp_path, fmu_paths):
    """The first SIGINT comes while the figures are drawn (the results are already written and
    complete; the first signal only asks to stop). The second one ends the command there: exit 130
    at once, the figures' staging folder and every temporary file removed, no traceback.

    The signal waits for the command's report (its first line on stdout, printed once the trace and
    records are in place) and then for the figures' staging folder (the figures being drawn): a first
    signal while the records are still being written skips the figures by itself, and on a fast
    machine the command has then ended before a second signal 50 ms later."""
    out = tmp_path / "run"
    process = popen_heliostep(
        ["run", str(SCENARIOS / "jan21-central.yaml"), "--out", str(out), "--set", "window.duration=120"],
        tmp_path / "tmp",
    )
    assert process.stdout is not None
    readable, _, _ = select.select([process.stdout], [], [], 60.0)  # the records reported, or the pipe closed
    assert readable, "the command reported nothing within 60 s"
    first_line = process.stdout.readline()  # the report is printed and flushed whole: its first line is there
    assert first_line.startswith("jan21-central: complete -> "), (first_line, process.communicate())
    deadline = time.monotonic() + 60.0
    while not _staged_figures(out):  # the drawing has begun (its staging folder)
        assert process.poll() is None, process.communicate()
        assert time.monotonic() < deadline, "no figures were drawn"
        time.sleep(0.005)
    _signal_twice(process, signal.SIGINT, 0.05, 130, out)
    figures = [p for p in out.iterdir() if p.suffix == ".png"]
    assert len(figures) < 7  # it did not go on drawing
    # what had been renamed into place before is whole and says complete: the run had finished
    trace, meta = read_trace(out / "trace.parquet")
    summary = json.loads((out / "summary.json").read_text())
    assert meta["complete"] == "true" and summary["complete"] is True and summary["rows"] == len(trace)
    assert trace["time"].iloc[-1] == 120.0
    assert _fmu_dirs(tmp_path / "tmp") == [], "FMU unpack folder left behind"


def _staged_figures(out: Path) -> list[Path]:
    """The figures' staging folders inside the run's staging folder; a folder renamed or removed while
    the glob walks it is simply not there (the run moves on as the test polls)."""
    try:
        return list(out.glob(".heliostep-tmp-*/.heliostep-tmp-figures-*"))
    except FileNotFoundError:
        return []


def test_second_signal_mid_simulation_removes_the_trace_stream(tmp_path, fmu_paths):
    """A long window streams its trace into --out; two SIGTERMs 30 ms apart: the first asks to
    stop, the second lands while the run stops (or computes its figures) and ends it at once. The
    half-finished stream is removed with everything else temporary."""
    out = tmp_path / "run"
    process = popen_heliostep(["run", str(five_day_scenario(tmp_path)), "--out", str(out)], tmp_path / "tmp")
    _wait_for_fmus(tmp_path / "tmp", process)
    deadline = time.monotonic() + 60.0  # the stream's file is made before the simulation starts
    while not list(out.glob(".heliostep-tmp-*-trace.parquet")):
        assert process.poll() is None, "the run ended before the signal"
        assert time.monotonic() < deadline, "the trace is not being streamed"
        time.sleep(0.01)
    time.sleep(0.5)  # into the simulation
    assert process.poll() is None, "the run ended before the signal"
    _signal_twice(process, signal.SIGTERM, 0.03, 143, out)
    for name in ("trace.parquet", "summary.json"):  # if it got as far as renaming, it says incomplete
        if (out / name).exists():
            assert "true" not in (
                read_trace(out / name)[1]["complete"]
                if name.endswith("parquet")
                else str(json.loads((out / name).read_text())["complete"]).lower()
            )
    assert _fmu_dirs(tmp_path / "tmp") == [], "FMU unpack folder left behind"
