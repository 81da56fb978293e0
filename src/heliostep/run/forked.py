"""Two pieces of work at once: one in a forked child process, one here (a run's figures on two cores).

:func:`in_parallel` forks a child that inherits everything this process holds (the trace, the
solution's plot data: nothing is sent to it), runs one piece of work there and the other here,
and returns both results; the child's result (or its exception, raised here as itself) comes back
pickled through a pipe. The child never returns into this process's code: it leaves with
``os._exit``, so no exit handler, ``finally`` block or finalizer of this process runs twice (a
result's temporary folder is removed by this process only). When this process's own work fails
or is stopped (a second signal: ``ForcedStop``), the child is killed and reaped before the
exception goes on.

Without a fork (Windows), on one core, with other threads running (a fork copies one thread, and
any lock another one held: a Dask worker's threads) or with ``HELIOSTEP_PARALLEL_PLOTS=0``, the two
pieces run here one after the other (:func:`can_fork`). A busy machine forks all the same: the child
imports nothing (a run's plotting modules are imported before the fork), so its share costs the
CPU it would cost here.
"""

from __future__ import annotations

import os
import pickle
import signal
import sys
import threading
import traceback
from collections.abc import Callable
from typing import Any

__all__ = ["can_fork", "in_parallel"]


def can_fork() -> bool:
    """Whether :func:`in_parallel` forks (see the module's docstring)."""
    choice = os.environ.get("HELIOSTEP_PARALLEL_PLOTS", "auto").strip().lower()
    if choice in ("0", "off", "no", "false"):
        return False
    return hasattr(os, "fork") and (os.cpu_count() or 1) > 1 and threading.active_count() == 1


def in_parallel(in_child: Callable[[], Any], here: Callable[[], Any]) -> tuple[Any, Any]:
    """``(in_child(), here())``, the first computed in a forked child while the second runs here.

    Raises the exception of either (the child's when both fail: it is the one that ran first
    in the serial order); a child that dies without a word (killed) is a RuntimeError.
    """
    if not can_fork():
        return in_child(), here()
    readable, writable = os.pipe()
    sys.stdout.flush()  # nothing buffered here may be written twice
    sys.stderr.flush()
    pid = os.fork()
    if pid == 0:  # the child
        status = 1
        try:
            os.close(readable)
            status = _serve(in_child, writable)
        finally:
            os._exit(status)
    os.close(writable)
    try:
        own = here()
        with os.fdopen(readable, "rb") as pipe:
            readable = -1
            payload = pipe.read()
        _, wait_status = os.waitpid(pid, 0)
    except BaseException:
        _end(pid, readable)
        raise
    if not payload:
        raise RuntimeError(f"the child process drawing a share of the figures died ({_said(wait_status)})")
    succeeded, value = pickle.loads(payload)
    if not succeeded:
        raise value
    return value, own


def _serve(work: Callable[[], Any], writable: int) -> int:
    """The child's part: ``work()``'s outcome pickled into ``writable``; the exit status."""
    try:
        outcome: tuple[bool, Any] = (True, work())
    except BaseException as exc:  # (a signal's exception too): sent back, raised by the parent
        exc.add_note("".join(["in the child process:\n", *traceback.format_exception(exc)]))
        outcome = (False, exc)
    try:
        payload = pickle.dumps(outcome)
    except Exception:  # an exception or a result that does not pickle: its text instead
        text = "".join(traceback.format_exception(outcome[1])) if not outcome[0] else repr(outcome[1])
        payload = pickle.dumps((False, RuntimeError(f"in the child process: {text}")))
    with os.fdopen(writable, "wb") as pipe:
        pipe.write(payload)
    return 0 if outcome[0] else 1


def _end(pid: int, readable: int) -> None:
    """The child killed and reaped, the pipe closed (this process's work failed or was stopped)."""
    try:
        os.kill(pid, signal.SIGKILL)
    except ProcessLookupError:
        pass
    try:
        os.waitpid(pid, 0)
    except ChildProcessError:
        pass
    if readable >= 0:
        os.close(readable)


def _said(wait_status: int) -> str:
    code = os.waitstatus_to_exitcode(wait_status)
    return f"killed by signal {-code}" if code < 0 else f"exit status {code}"
