"""SIGHUP is handled as SIGTERM, and a stop signal at any moment of the start (while the modules
are imported) is one line, never a traceback (issue 22, items 8 and 13).

Real ``heliostep run`` subprocesses, real signals, real FMUs.
"""

from __future__ import annotations

import glob
import json
import signal
import subprocess
import time
from pathlib import Path

import pytest

from heliostep.paths import scenarios_dir
from heliostep.results.trace.files import read_trace
from heliostep_process import popen_heliostep


def _wait_for_numpy(process: subprocess.Popen) -> None:
    """Until the child has loaded numpy's C core: the commands' modules are being imported (numpy
    comes with the first of them, after ``heliostep.cli.main`` has installed its handlers; a
    signal before that lands in Python's own start-up, where nothing of heliostep runs)."""
    maps = Path(f"/proc/{process.pid}/maps")
    deadline = time.monotonic() + 60
    while "_multiarray_umath" not in maps.read_text():
        assert process.poll() is None and time.monotonic() < deadline, process.communicate()
        time.sleep(0.002)


@pytest.mark.skipif(not Path("/proc/self/maps").exists(), reason="needs Linux's /proc to see the imports")
@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM, signal.SIGHUP])
@pytest.mark.parametrize("delay", [0.0, 0.25])
def test_a_stop_signal_during_the_imports_is_one_line_and_its_exit_status(sig, delay, tmp_path, fmu_paths):
    process = popen_heliostep(["run", "jan21-central", "--out", str(tmp_path / "out")], tmp_path / "tmp")
    _wait_for_numpy(process)
    time.sleep(delay)  # the command's modules (pandas, pvlib, matplotlib, ...) are being imported
    process.send_signal(sig)
    stdout, stderr = process.communicate(timeout=60)
    assert process.returncode == 128 + sig, stderr
    assert "Traceback" not in stderr and "KeyboardInterrupt" not in stderr, stderr
    assert len(stderr.strip().splitlines()) == 1 and f"stopped by {sig.name}" in stderr, stderr
    assert list((tmp_path / "tmp").iterdir()) == []


def test_sighup_mid_simulation_keeps_the_trace_so_far_and_leaves_no_temporary_file(tmp_path, fmu_paths):
    text = (scenarios_dir() / "jan21-day.yaml").read_text().replace("end: sunset", "duration: 432000")
    scenario = tmp_path / "five-days.yaml"
    scenario.write_text(text.replace("name: jan21-day", "name: five-days"))
    out, tmp = tmp_path / "out", tmp_path / "tmp"
    process = popen_heliostep(["run", str(scenario), "--out", str(out)], tmp)
    deadline = time.monotonic() + 60
    while not list(out.glob(".heliostep-tmp-*-trace.parquet")):  # streaming: simulating
        assert process.poll() is None and time.monotonic() < deadline, process.communicate()
        time.sleep(0.01)
    time.sleep(1.0)
    process.send_signal(signal.SIGHUP)  # a closed terminal
    _, stderr = process.communicate(timeout=60)
    assert process.returncode == 129, stderr
    assert "Traceback" not in stderr and "stopped by SIGHUP" in stderr
    summary = json.loads((out / "summary.json").read_text())
    trace, meta = read_trace(out / "trace.parquet")
    assert summary["complete"] is False and summary["reason"] == "interrupted"
    assert meta["reason"] == "interrupted" and summary["rows"] == len(trace) > 10
    assert trace["time"].iloc[-1] == pytest.approx(summary["time_reached_s"])
    assert not list(out.glob(".heliostep-tmp-*")) and not (out / ".heliostep-lock").exists()
    assert list(tmp.iterdir()) == [], "FMU unpack folder or temporary file left behind"


def test_sighup_while_the_figures_are_drawn_keeps_the_results_and_no_figure_folder(tmp_path, fmu_paths):
    out, tmp = tmp_path / "out", tmp_path / "tmp"
    process = popen_heliostep(["run", "jan21-central", "--out", str(out), "--set", "window.duration=120"], tmp)
    deadline = time.monotonic() + 60
    while not glob.glob(str(out / ".heliostep-tmp-*" / ".heliostep-tmp-figures-*")):  # drawing has begun
        assert process.poll() is None and time.monotonic() < deadline, process.communicate()
        time.sleep(0.005)
    process.send_signal(signal.SIGHUP)
    _, stderr = process.communicate(timeout=60)
    assert process.returncode == 129 and "Traceback" not in stderr, stderr
    summary = json.loads((out / "summary.json").read_text())
    assert summary["complete"] is True  # the run had finished: its results are whole
    assert not list(out.glob(".heliostep-tmp-*")), "a temporary (figure) folder was left"
    assert list(tmp.iterdir()) == []
    # a rerun finds nothing of it left behind and writes every figure
    rerun = popen_heliostep(["run", "jan21-central", "--out", str(out), "--set", "window.duration=120"], tmp)
    _, stderr = rerun.communicate(timeout=120)
    assert rerun.returncode == 0, stderr
    assert len(list(out.glob("*.png"))) == 8 and not list(out.glob(".heliostep-tmp-*"))
