"""Tests of heliostep.run.forked (work in a forked child beside this process; a helper forked before its work)
and of a run's figures drawn on two cores (and, by ``RunResult.write``, while the records are written, also by
the command line's drawer): the same PNGs, byte for byte, as drawn one after the other. Real forks, real
signals."""

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
from heliostep.run.forked import Helper, can_fork, in_parallel
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


def _who_am_i(payload: bytes) -> tuple[int, int, int]:
    return os.getpid(), os.getpgid(0), len(payload)


def _wait_for(path: Path) -> None:
    deadline = time.monotonic() + 20.0
    while not path.exists():
        if time.monotonic() > deadline:
            raise TimeoutError(f"{path} never appeared")
        time.sleep(0.01)


def _sleeping_grandchild(pid_file: Path) -> None:
    pid = os.fork()
    if pid == 0:
        time.sleep(60.0)
        os._exit(0)
    pid_file.write_text(str(pid))
    time.sleep(60.0)


def _gone(pid: int) -> bool:
    """No such process, or a zombie only (killed; reaped by whoever adopted it)."""
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except FileNotFoundError:
        return True
    return state in ("Z", "X")


def test_a_helper_prepares_while_this_side_goes_on_then_runs_the_call_in_its_own_process_group(forking, tmp_path):
    submitted = tmp_path / "submitted"
    helper = Helper.start(lambda: _wait_for(submitted))  # prepares until this side has submitted: never waited for
    assert helper is not None
    with helper:
        assert helper.alive()  # preparing: there to be sent its call
        big = b"x" * 5_000_000  # far more than a pipe holds: it goes through the spool file
        helper.submit(_who_am_i, (big,), tmp_path / "job.pickle")
        assert not helper.alive()  # sent one: no second
        submitted.touch()
        pid, group, size = helper.result()
    assert pid == helper.pid != os.getpid() and group == helper.pid != os.getpgid(0) and size == len(big)
    assert not (tmp_path / "job.pickle").exists()  # the child removed the spool
    with pytest.raises(ProcessLookupError):  # reaped
        os.kill(helper.pid, 0)


def test_a_failed_preparation_is_the_calls_exception_and_a_helper_asked_nothing_leaves_by_itself(forking, tmp_path):
    def broken():
        raise ImportError("no module named 'matplotlib'")

    helper = Helper.start(broken)
    with helper, pytest.raises(ImportError, match="matplotlib") as raised:
        helper.submit(_who_am_i, (b"",), tmp_path / "job.pickle")
        helper.result()
    assert any("in the child process" in note for note in raised.value.__notes__)
    idle = Helper.start(lambda: None)
    os.close(idle._job)  # this side closes the pipe without a call (as when it dies)
    idle._job = -1
    _, status = os.waitpid(idle.pid, 0)
    idle._reaped = True
    assert os.waitstatus_to_exitcode(status) == 0
    idle.close()


#: what a helper's preparation saw and made (set in the child, read there by _collector_state)
_PREPARED: dict = {}


def _prepare_objects() -> None:
    import gc

    _PREPARED["collector on"] = gc.isenabled()
    _PREPARED["made"] = [[index] for index in range(30_000)]  # 30 001 containers the collector tracks


def _collector_state() -> tuple[bool, bool, int]:
    import gc

    return _PREPARED["collector on"], gc.isenabled(), gc.get_freeze_count()


def test_a_helper_prepares_without_the_collector_and_freezes_what_it_made(forking, tmp_path):
    import gc

    assert gc.isenabled()
    helper = Helper.start(_prepare_objects)
    assert helper is not None
    with helper:
        helper.submit(_collector_state, (), tmp_path / "job.pickle")
        on_while_preparing, on_after, frozen = helper.result()
    assert not on_while_preparing and on_after  # off while it imports, on again for its call
    assert frozen >= 30_001  # what it prepared (and all it inherited) is never scanned again
    assert gc.isenabled() and gc.get_freeze_count() == 0  # this process's collector untouched


def test_closing_a_helper_kills_it_and_what_it_forked_and_reaps_it(forking, tmp_path):
    pid_file = tmp_path / "grandchild.pid"
    helper = Helper.start(lambda: None)
    helper.submit(_sleeping_grandchild, (pid_file,), tmp_path / "job.pickle")
    _wait_for(pid_file)
    while not pid_file.read_text():
        time.sleep(0.01)
    started = time.monotonic()
    helper.close()
    assert time.monotonic() - started < 30.0  # not the 60 s sleep
    with pytest.raises(ProcessLookupError):
        os.kill(helper.pid, 0)
    grandchild = int(pid_file.read_text())
    deadline = time.monotonic() + 10.0
    while not _gone(grandchild) and time.monotonic() < deadline:  # its group was killed with it
        time.sleep(0.01)
    assert _gone(grandchild)


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
import signal
from heliostep.run.drawing import start_drawer
with start_drawer() as drawer:  # the command line's: forked before, the plotting modules imported meanwhile
    files = result.write(out / "drawer", drawer=drawer)
drawer_pngs = [str(files[name]) for name in files if name.endswith(".png")]
with start_drawer() as drawer:  # one that ended before it was needed (killed): drawn as without it
    os.kill(drawer.pid, signal.SIGKILL)
    os.waitid(os.P_PID, drawer.pid, os.WEXITED | os.WNOWAIT)  # (ended, left for alive() to reap)
    alive = drawer.alive()
    files = result.write(out / "killed", drawer=drawer)
drawer_pngs += [str(files[name]) for name in files if name.endswith(".png")] if not alive else ["alive?"]
object.__setattr__(result.solution_plot, "unpicklable", lambda: None)  # a part of the job that does not pickle
with start_drawer() as drawer:
    files = result.write(out / "unpicklable", drawer=drawer)
drawer_pngs += [str(files[name]) for name in files if name.endswith(".png")]
object.__delattr__(result.solution_plot, "unpicklable")  # (drawn without the drawer, the same PNGs)
os.environ["HELIOSTEP_PARALLEL_PLOTS"] = "0"
serial = [str(path) for path in result.plot(out / "serial")]
print(json.dumps({"forks": forks, "parallel": parallel, "written": written, "drawer": drawer_pngs, "serial": serial}))
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
    parallel, written, drawer, serial = [
        [Path(name) for name in report[key]] for key in ("parallel", "written", "drawer", "serial")
    ]
    assert [path.name for path in parallel] == [path.name for path in serial] == [*FIGURE_FILES, POWER_FILE]
    every = sorted([*FIGURE_FILES, POWER_FILE])
    assert sorted(path.name for path in written) == every and sorted(path.name for path in drawer) == sorted(3 * every)
    for drawn, alone in zip(parallel, serial):
        assert drawn.read_bytes() == alone.read_bytes(), drawn.name
        assert drawn.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    for drawn in [*written, *drawer]:  # a run's write(): drawn while its records were written, the same PNGs
        assert drawn.read_bytes() == (serial[0].parent / drawn.name).read_bytes(), drawn.name
