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

:class:`Helper` is a child forked before its work exists: it prepares (a run's plotting modules
imported, 0.2 s) while this process simulates, then runs the one call this process sends it.
"""

from __future__ import annotations

import os
import pickle
import signal
import sys
import threading
import traceback
from collections.abc import Callable
from pathlib import Path
from typing import Any

from heliostep.collector import imports_frozen

__all__ = ["Helper", "can_fork", "in_parallel"]


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

    def child() -> int:
        os.close(readable)
        return _serve(in_child, writable)

    pid = _fork(child)
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
    return _outcome(payload, wait_status, "the child process drawing a share of the figures"), own


class Helper:
    """A child forked now that prepares (``prepare()``, e.g. imports) while this process goes on, then
    runs the one call this process sends it (:meth:`submit`) and sends back its outcome (:meth:`result`).

    Call order: :meth:`start` (None where :func:`can_fork` says no), then at most one :meth:`submit`
    (where :meth:`alive`) and its :meth:`result`, and :meth:`close` in every case (a context manager: on
    leaving the block).

    - The call (a function pickled by name, and its arguments) is pickled into a file, ``spool``, and
      only the file's name goes through the pipe: :meth:`submit` never waits for a child that is
      still preparing, however large the arguments. A ``prepare()`` that failed is the call's
      exception, raised by :meth:`result` as :func:`in_parallel` raises the child's.
    - The child leads a process group of its own: a terminal's Ctrl+C reaches this process only,
      which decides; :meth:`close` kills the whole group (the child and what it forked itself) and
      reaps the child. Its signal handlers are the default ones (a signal sent to it ends it).
    - The child leaves when this process closes the pipe without a call, and after its call, always
      with ``os._exit`` (no exit handler or finalizer of this process runs twice).
    - ``prepare()`` runs without the garbage collector, and what is alive after it is frozen
      (:func:`heliostep.collector.imports_frozen`): a drawer's first full collection used to come when its
      job had arrived, 70 ms on the figures' critical path.
    """

    def __init__(self, pid: int, job: int, reply: int):
        self.pid, self._job, self._reply = pid, job, reply
        self._reaped = False

    @classmethod
    def start(cls, prepare: Callable[[], None]) -> Helper | None:
        """The child forked, ``prepare()`` running in it; None (nothing forked) where it cannot fork."""
        if not can_fork():
            return None
        job_read, job_write = os.pipe()
        reply_read, reply_write = os.pipe()

        def child() -> int:
            os.setpgid(0, 0)
            os.close(job_write)
            os.close(reply_read)
            return _help(prepare, job_read, reply_write)

        pid = _fork(child)
        try:
            os.setpgid(pid, pid)  # (also here: the group exists before close() may kill it)
        except (PermissionError, ProcessLookupError):
            pass  # the child did it first, or has already ended
        os.close(job_read)
        os.close(reply_write)
        return cls(pid, job_write, reply_read)

    def alive(self) -> bool:
        """Whether the child is there to be sent its call: not ended (killed, crashed), not sent one yet."""
        if self._reaped or self._job < 0:
            return False
        try:
            pid, _ = os.waitpid(self.pid, os.WNOHANG)
        except ChildProcessError:
            pid = self.pid
        if pid == 0:
            return True
        self._reaped = True  # ended: reaped just now
        return False

    def submit(self, function: Callable[..., Any], arguments: tuple, spool: Path) -> None:
        """``function(*arguments)`` sent to the child, pickled into the file ``spool`` (removed by the child).
        A child that ended meanwhile is :meth:`result`'s RuntimeError."""
        with open(spool, "wb") as file:
            pickle.dump((function, arguments), file, protocol=pickle.HIGHEST_PROTOCOL)
        try:
            os.write(self._job, os.fsencode(spool) + b"\n")
        except BrokenPipeError:
            pass  # the child has ended: result() finds its pipe closed and says so
        finally:
            os.close(self._job)
            self._job = -1

    def result(self) -> Any:
        """The call's value, or its exception raised here as itself; a child that died without a word
        (killed) is a RuntimeError. Waits for the child; on any exception here, :meth:`close`."""
        try:
            with os.fdopen(self._reply, "rb") as pipe:
                self._reply = -1
                payload = pipe.read()
            _, wait_status = os.waitpid(self.pid, 0)
            self._reaped = True
        except BaseException:
            self.close()
            raise
        return _outcome(payload, wait_status, "the helper process drawing the figures")

    def close(self) -> None:
        """The child's process group killed and the child reaped (unless done), the pipes closed."""
        if not self._reaped:
            _kill_and_reap(self.pid, group=True)
            self._reaped = True
        for name in ("_job", "_reply"):
            if getattr(self, name) >= 0:
                os.close(getattr(self, name))
                setattr(self, name, -1)

    def __enter__(self) -> Helper:
        return self

    def __exit__(self, *exc_info) -> None:
        self.close()


def _help(prepare: Callable[[], None], job: int, reply: int) -> int:
    """The helper child's part: ``prepare()``, then the call named in ``job`` (nothing: status 0)."""
    for number in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):
        signal.signal(number, signal.SIG_DFL)
    try:
        with imports_frozen():  # what it imports is this child's for its life: never scanned again
            prepare()
        prepared: BaseException | None = None
    except BaseException as exc:  # reported as the call's outcome
        prepared = exc
    with os.fdopen(job, "rb") as pipe:
        line = pipe.readline()
    if not line.endswith(b"\n"):
        return 0  # closed without a call: nothing asked
    spool = Path(os.fsdecode(line[:-1]))

    def call() -> Any:
        if prepared is not None:
            raise prepared
        with open(spool, "rb") as file:
            function, arguments = pickle.load(file)
        spool.unlink(missing_ok=True)
        return function(*arguments)

    return _serve(call, reply)


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


def _fork(child: Callable[[], int]) -> int:
    """A child forked to run ``child()`` and leave with its exit status (``os._exit``: nothing of this
    process's runs twice there, exit handlers, finalizers or buffered output); its pid."""
    sys.stdout.flush()  # nothing buffered here may be written twice
    sys.stderr.flush()
    pid = os.fork()
    if pid == 0:  # the child
        status = 1
        try:
            status = child()
        finally:
            os._exit(status)
    return pid


def _outcome(payload: bytes, wait_status: int, who: str) -> Any:
    """What :func:`_serve` sent (``payload``): the value, or the exception raised here as itself; nothing
    (``who`` died without a word: killed) is a RuntimeError naming how it ended."""
    if not payload:
        raise RuntimeError(f"{who} died ({_said(wait_status)})")
    succeeded, value = pickle.loads(payload)
    if not succeeded:
        raise value
    return value


def _kill_and_reap(pid: int, group: bool = False) -> None:
    """The child ``pid`` (with ``group``, its whole process group) killed and reaped."""
    try:
        if group:
            os.killpg(pid, signal.SIGKILL)
        else:
            os.kill(pid, signal.SIGKILL)
    except (ProcessLookupError, PermissionError):
        pass
    try:
        os.waitpid(pid, 0)
    except ChildProcessError:
        pass


def _end(pid: int, readable: int) -> None:
    """The child killed and reaped, the pipe closed (this process's work failed or was stopped)."""
    _kill_and_reap(pid)
    if readable >= 0:
        os.close(readable)


def _said(wait_status: int) -> str:
    code = os.waitstatus_to_exitcode(wait_status)
    return f"killed by signal {-code}" if code < 0 else f"exit status {code}"
