"""``heliostep`` leaves without Python's teardown (``heliostep.cli.leave``), losing nothing an exit must do.

Real processes: small programs that end with :func:`heliostep.cli.leave` as the installed command does
(:func:`heliostep.cli.console_main`), and the command itself on 10 s of the paper's case. What an exit must
still do is checked from outside: the exit status, the output still in stdout's buffer (a pipe is block
buffered), the exit handlers (``atexit``, ``weakref.finalize``), a thread still working (Python's exit waits
for it) and a closed pipe (reported, not a success).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap

import pyarrow.parquet as pq

from heliostep.paths import scenarios_dir
from heliostep_process import HELIOSTEP


def run_program(body: str, tmp_path, **kwargs) -> subprocess.CompletedProcess:
    """``body`` run in a new interpreter whose stdout and stderr are buffered as by default (a pipe: block
    buffered; not PYTHONUNBUFFERED, which would write every call at once), ``sys.argv[1]`` its folder."""
    program = "import sys\nfrom heliostep.cli import leave\n" + textwrap.dedent(body)
    environment = {name: value for name, value in os.environ.items() if name != "PYTHONUNBUFFERED"}
    return subprocess.run([sys.executable, "-c", program, str(tmp_path)], env=environment, timeout=120, **kwargs)


def test_leave_keeps_the_status_the_buffered_output_and_the_exit_handlers(tmp_path):
    done = run_program(
        """
        import atexit, pathlib, weakref
        folder = pathlib.Path(sys.argv[1])
        atexit.register(lambda: (folder / "atexit").write_text("ran"))
        class Held: pass
        held = Held()
        weakref.finalize(held, lambda: (folder / "finalizer").write_text("ran"))
        sys.stdout.write("x" * 5000 + " the end")  # no newline: still in the pipe's buffer
        sys.stderr.write("a line on stderr")
        leave(3)
        """,
        tmp_path,
        capture_output=True,
        text=True,
    )
    assert done.returncode == 3
    assert done.stdout == "x" * 5000 + " the end" and done.stderr == "a line on stderr"
    assert (tmp_path / "atexit").read_text() == "ran" and (tmp_path / "finalizer").read_text() == "ran"


def test_leave_waits_for_a_thread_still_working_as_pythons_exit_does(tmp_path):
    done = run_program(
        """
        import pathlib, threading, time
        def work():
            time.sleep(0.5)
            (pathlib.Path(sys.argv[1]) / "thread").write_text("finished")
        threading.Thread(target=work).start()
        leave(0)
        """,
        tmp_path,
        capture_output=True,
        text=True,
    )
    assert done.returncode == 0, done.stderr
    assert (tmp_path / "thread").read_text() == "finished"


def test_output_that_cannot_be_written_is_not_a_success(tmp_path):
    reader, writer = os.pipe()
    os.close(reader)  # nobody reads: flushing stdout fails (EPIPE)
    try:
        done = run_program(
            """
            sys.stdout.write("lost")
            leave(0)
            """,
            tmp_path,
            stdout=writer,
            stderr=subprocess.PIPE,
            text=True,
        )
    finally:
        os.close(writer)
    assert done.returncode == 120  # Python's own status for a stream it could not flush at exit
    assert "BrokenPipeError" in done.stderr


def test_the_installed_command_leaves_with_its_report_and_files_whole(tmp_path):
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


#: The installed command's path (:func:`heliostep.cli.console_main`) on 10 s of the paper's case, with an exit
#: handler that signals the process while the exit handlers run (the FMUs' unpack folders are removed there),
#: ``SIGNALS`` times; ``LEAVING``: the handlers kept for the exit, as the installed command keeps them.
SIGNALLED_EXIT = """
import atexit, os, pathlib, signal
from heliostep.cli import main
folder = pathlib.Path(sys.argv[1])

def clean_up():  # registered first: runs last, after heliostep's own exit handlers
    for _ in range(SIGNALS):
        os.kill(os.getpid(), signal.SIGINT)
        sum(range(10**5))  # (the handler runs between two bytecodes here)
    (folder / "cleaned").write_text("the clean-up went on")

atexit.register(clean_up)
status = main(
    ["run", SCENARIO, "--out", str(folder / "run"), "--no-plots", "--set", "window.duration=10"],
    freeze_imports=True,
    leaving=LEAVING,
)
leave(status)
"""


def _signalled_exit(tmp_path, signals: int, leaving: bool) -> subprocess.CompletedProcess:
    scenario = repr(str(scenarios_dir() / "jan21-central.yaml"))
    body = SIGNALLED_EXIT.replace("SCENARIO", scenario).replace("SIGNALS", str(signals))
    return run_program(body.replace("LEAVING", str(leaving)), tmp_path, capture_output=True, text=True)


def test_a_signal_while_the_command_leaves_lets_the_clean_up_finish_and_keeps_its_status(tmp_path, fmu_paths):
    done = _signalled_exit(tmp_path, signals=1, leaving=True)
    assert done.returncode == 0 and "Traceback" not in done.stderr and "ignored" not in done.stderr, done.stderr
    assert (tmp_path / "cleaned").read_text() == "the clean-up went on"
    assert json.loads((tmp_path / "run" / "summary.json").read_text())["complete"] is True


def test_a_second_signal_while_the_command_leaves_ends_it_at_once(tmp_path, fmu_paths):
    done = _signalled_exit(tmp_path, signals=2, leaving=True)
    assert done.returncode == 130 and "Traceback" not in done.stderr, done.stderr
    assert not (tmp_path / "cleaned").exists()  # ended at the second, as asked


def test_without_the_handlers_kept_for_the_exit_the_signal_is_a_traceback_in_the_clean_up(tmp_path, fmu_paths):
    """The control (``main`` called from Python restores the caller's handlers: Python's own, here): the
    signal raises KeyboardInterrupt inside the exit handler, which Python prints and drops."""
    done = _signalled_exit(tmp_path, signals=1, leaving=False)
    assert "Exception ignored in atexit callback" in done.stderr and "KeyboardInterrupt" in done.stderr, done.stderr
    assert not (tmp_path / "cleaned").exists()
