"""Tests of heliostep.run.forked (work in a forked child beside this process) and of a run's figures drawn
on two cores (and, by ``RunResult.write``, while the records are written): the same PNGs, byte for byte, as
drawn one after the other. Real forks, real signals."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from heliostep.paths import scenarios_dir
from heliostep.results.run_files import FIGURE_FILES, POWER_FILE
from heliostep.run import forked
from heliostep.run.forked import can_fork, in_parallel
from heliostep.run.result import CHILD_FIGURES, OWN_FIGURES


@pytest.fixture
def forking(monkeypatch):
    """in_parallel forks: whatever the machine's load, and whatever thread an earlier test left running (the
    children here touch no lock another thread could hold; a run's figures are tested in a fresh process)."""
    monkeypatch.setenv("HELIOSTEP_PARALLEL_PLOTS", "1")
    monkeypatch.setattr(forked.threading, "active_count", lambda: 1)
    assert can_fork()


def test_the_child_works_in_another_process_and_its_result_comes_back(forking):
    here = os.getpid()
    theirs, ours = in_parallel(lambda: (os.getpid(), [1.5, "two"]), lambda: os.getpid())
    assert ours == here and theirs[0] != here and theirs[1] == [1.5, "two"]


def test_the_childs_exception_is_raised_here_as_itself_and_a_killed_child_is_named(forking):
    def full_disk():
        raise OSError(28, "No space left on device")

    with pytest.raises(OSError) as raised:
        in_parallel(full_disk, lambda: None)
    assert raised.value.errno == 28 and any("in the child process" in note for note in raised.value.__notes__)
    with pytest.raises(RuntimeError, match="killed by signal 9"):
        in_parallel(lambda: os.kill(os.getpid(), signal.SIGKILL), lambda: None)


def test_when_this_side_fails_the_child_is_killed_and_reaped(forking, tmp_path):
    pid_file = tmp_path / "child.pid"

    def slow_child():
        pid_file.write_text(str(os.getpid()))
        time.sleep(60.0)

    def failing_here():
        while not pid_file.exists() or not pid_file.read_text():  # the child has started
            time.sleep(0.01)
        raise ValueError("this side failed")

    started = time.monotonic()
    with pytest.raises(ValueError, match="this side failed"):
        in_parallel(slow_child, failing_here)
    assert time.monotonic() - started < 30.0  # not the child's 60 s
    with pytest.raises(ProcessLookupError):  # killed and reaped: no such process, not even a zombie
        os.kill(int(pid_file.read_text()), 0)


def test_without_forking_both_run_here_one_after_the_other(monkeypatch):
    monkeypatch.setenv("HELIOSTEP_PARALLEL_PLOTS", "0")
    assert not can_fork()
    order = []
    theirs, ours = in_parallel(lambda: order.append("child") or os.getpid(), lambda: order.append("here") or 7)
    assert (theirs, ours, order) == (os.getpid(), 7, ["child", "here"])


#: In a fresh interpreter (one thread: it forks as a run does): a run's figures drawn on two cores, then in one.
DRAW_BOTH_WAYS = """
import json, os, sys
from pathlib import Path
from heliostep.run import run_scenario
from heliostep.run.forked import can_fork
result = run_scenario(sys.argv[1], overrides=("window.duration=60",))
out = Path(sys.argv[2])
os.environ["HELIOSTEP_PARALLEL_PLOTS"] = "1"
forks = can_fork()
parallel = [str(path) for path in result.plot(out / "parallel")]
files = result.write(out / "written")  # drawn by a forked child while the records are written
written = [str(files[name]) for name in sorted(files, key=list(files).index) if name.endswith(".png")]
os.environ["HELIOSTEP_PARALLEL_PLOTS"] = "0"
serial = [str(path) for path in result.plot(out / "serial")]
print(json.dumps({"forks": forks, "parallel": parallel, "written": written, "serial": serial}))
"""


def test_the_figures_drawn_on_two_cores_are_those_drawn_in_one_process_byte_for_byte(tmp_path):
    assert sorted([*CHILD_FIGURES, *OWN_FIGURES]) == sorted(FIGURE_FILES)  # every figure drawn by one side
    scenario = str(scenarios_dir() / "jan21-central.yaml")
    done = subprocess.run(
        [sys.executable, "-c", DRAW_BOTH_WAYS, scenario, str(tmp_path)], capture_output=True, text=True
    )
    assert done.returncode == 0, done.stderr
    report = json.loads(done.stdout.strip().splitlines()[-1])
    assert report["forks"] is True
    parallel, written, serial = [[Path(name) for name in report[key]] for key in ("parallel", "written", "serial")]
    assert [path.name for path in parallel] == [path.name for path in serial] == [*FIGURE_FILES, POWER_FILE]
    assert sorted(path.name for path in written) == sorted(path.name for path in serial)
    for drawn, alone in zip(parallel, serial):
        assert drawn.read_bytes() == alone.read_bytes(), drawn.name
        assert drawn.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    for drawn in written:  # a run's write(): drawn while its records were written, the same PNGs
        assert drawn.read_bytes() == (serial[0].parent / drawn.name).read_bytes(), drawn.name
