"""A stop that comes before the simulation starts still leaves ``summary.json`` (``complete: false``, reason
interrupted, the stage reached), and the exit status stays 128 + the signal's number.

A real ``heliostep run`` in a subprocess, signalled once it holds its --out's lock (a state waited for, with
a bound).
"""

from __future__ import annotations

import json
import signal
import time

import pytest

from heliostep.results.output.folder import LOCK_NAME, MANIFEST_NAME
from heliostep_process import five_day_scenario, popen_heliostep


def _wait_for_lock(out, process, timeout: float = 120.0) -> None:
    deadline = time.monotonic() + timeout
    lock = out / LOCK_NAME
    while not (lock.exists() and str(process.pid) in lock.read_text()):
        assert process.poll() is None, process.communicate()
        assert time.monotonic() < deadline, "the run did not take its lock"
        time.sleep(0.01)


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_a_stop_once_the_folder_is_held_leaves_summary_json_with_the_stage_reached(sig, tmp_path, fmu_paths):
    out = tmp_path / "out"
    process = popen_heliostep(["run", str(five_day_scenario(tmp_path)), "--out", str(out), "--no-plots"])
    try:
        _wait_for_lock(out, process)
        process.send_signal(sig)
        _, err = process.communicate(timeout=120)
    finally:
        if process.poll() is None:
            process.kill()
            process.communicate()
    assert process.returncode == 128 + sig, err[-2000:]
    summary = json.loads((out / "summary.json").read_text())
    assert summary["complete"] is False and summary["reason"] == "interrupted", summary
    # where the stop lands depends on the machine: each stage before the simulation, or in it, is said
    assert summary["stage"] in ("starting", "preparing_inputs", "simulating"), summary
    assert "summary.json" in json.loads((out / MANIFEST_NAME).read_text())["files"]
    assert "Traceback" not in err
