"""A standard output that fails (a full device, a reader gone, a descriptor closed at start) changes neither a
run's files nor its exit status: written results stay a success, bad input stays exit 2, and standard error says
once that the printed report was lost."""

from __future__ import annotations

import json
import os
import subprocess

import pytest

from heliostep_process import HELIOSTEP


def _run(args: list[str], **stdout) -> subprocess.CompletedProcess:
    return subprocess.run([*HELIOSTEP, *args], stderr=subprocess.PIPE, text=True, timeout=300, **stdout)


def _closed_pipe() -> int:
    """The writing end of a pipe whose reader is gone (a write fails with EPIPE)."""
    read, write = os.pipe()
    os.close(read)
    return write


@pytest.mark.parametrize("broken", ["full device", "reader gone", "closed at start"])
def test_a_run_whose_stdout_fails_writes_its_results_and_exits_0(broken, tmp_path, fmu_paths):
    out = tmp_path / "out"
    args = ["run", "jan21-central", "--no-plots", "--out", str(out)]
    if broken == "full device":
        with open("/dev/full", "w") as full:
            done = _run(args, stdout=full)
    elif broken == "reader gone":
        pipe = _closed_pipe()
        try:
            done = _run(args, stdout=pipe)
        finally:
            os.close(pipe)
    else:
        done = _run(args, stdout=subprocess.DEVNULL, preexec_fn=lambda: os.close(1))
    assert done.returncode == 0, done.stderr
    assert "Traceback" not in done.stderr
    summary = json.loads((out / "summary.json").read_text())
    assert summary["complete"] is True
    assert (out / "trace.parquet").stat().st_size > 0
    lost = done.stderr.count("standard output failed")
    assert lost == (0 if broken == "closed at start" else 1), done.stderr  # closed: nothing to lose, no warning


def test_bad_input_with_a_failing_stdout_stays_exit_2(tmp_path):
    with open("/dev/full", "w") as full:
        args = ["run", "jan21-central", "--set", "sequencer.current=-1", "--out", str(tmp_path / "o")]
        done = _run(args, stdout=full)
    assert done.returncode == 2
    assert "sequencer" in done.stderr and "Traceback" not in done.stderr
