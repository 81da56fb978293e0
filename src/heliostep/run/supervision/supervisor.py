"""Supervised simulation: the master runs in a child process, so an FMU cannot take the run down.

:func:`simulate_supervised` is :meth:`CoSimulation.simulate <heliostep.cosim.master.CoSimulation.simulate>`
with the same arguments and results, but the simulation runs in a child process
(:mod:`heliostep.run.supervision.child`): forked from this process, or, where the caller says this process runs
threads (a Dask worker: a fork copies one thread, and any lock another one held), started by the
standard library's ``multiprocessing`` fork server (``start_method``). The child's monitor computes the
figures where the rows are made and streams its totals back over a socket with the trace rows: the
supervisor (this process) feeds the rows to the run's row sink and the totals to its monitor as they
come, so the figures and the trace are those of the master in-process, bit for bit.

When an FMU crashes the child (a segmentation fault, ``abort()``, the FMU calling ``exit`` —
even ``exit(0)``: only the child's explicit ``done`` is a success), the supervisor raises
:class:`FMUCrashed`; when no FMI call begins for ``watchdog`` seconds (an FMU looping inside a
call), it kills the child and raises :class:`FMUHung`. Both are
:class:`~heliostep.cosim.master.SimulationError` with ``reason`` ``"fmu-crashed"`` /
``"fmu-hung"`` and name the FMU instance, its model and the FMI call it was in, read from the
call record the child keeps in a file both processes map (:mod:`heliostep.cosim.watch`), and carry
the FMU's time then. Every row the child computed is in the sink and shown to the monitor: those
received, then those its journal (:mod:`heliostep.run.supervision.journal`) kept unsent: the run keeps
its trace and figures so far, marked.

A stop request (``should_stop``) is passed to the child, which stops at its next safe point;
a child that does not stop within :data:`STOP_GRACE` (an FMU stuck in a call) is killed, and the
run ends as interrupted with the rows so far. The child's temporary files (its unpacked FMUs,
the call record) are in a folder of the supervisor's, removed on every path.
"""

from __future__ import annotations

import mmap
import multiprocessing
import os
import pickle
import shutil
import signal
import socket
import struct
import sys
import tempfile
import threading
import time as clock
from collections.abc import Callable
from multiprocessing.connection import Connection
from pathlib import Path
from typing import Literal

import numpy as np
import pandas as pd

from heliostep.cosim import CoSimulation, MasterResult, SimulationError, SolverOptions
from heliostep.cosim.kernel import library_path
from heliostep.cosim.rows import RowBuffer
from heliostep.cosim.watch import LAYOUT, RECORD_BYTES, STOP_OFFSET, called_function
from heliostep.errors import HeliostepError, InputError, RunFailure
from heliostep.run.supervision.child import Request, SupervisedMonitor, run, serve
from heliostep.run.supervision.journal import Journal

__all__ = ["DEFAULT_WATCHDOG", "STOP_GRACE", "FMUCrashed", "FMUHung", "StartMethod", "simulate_supervised"]

#: Seconds without a new FMI call (and without a message from the child) before the supervisor
#: declares the FMU hung (a model evaluation takes microseconds to milliseconds).
DEFAULT_WATCHDOG = 60.0

#: How the child is started: ``"fork"`` from this process (nothing to import again; for a process
#: that runs one thread), or ``"forkserver"``, forked by ``multiprocessing``'s fork server (a
#: single-threaded process started once, the child's modules imported there; for a process that runs
#: threads, such as a Dask worker).
StartMethod = Literal["fork", "forkserver"]


#: Seconds a child has to stop by itself once asked, before it is killed.
STOP_GRACE = 1.0

#: Seconds the child may take to start (interpreter, imports, the request) before the watchdog
#: runs, if longer than the watchdog itself.
STARTUP_LIMIT = 120.0

#: Bytes of socket buffer asked for each way (the system may give less: ``net.core.wmem_max``).
SOCKET_BUFFER = 4 << 20

_POLL = 0.05  # [s] the supervisor's longest wait for a message before it looks at the child


class FMUCrashed(SimulationError):
    """The child process died in (or after) an FMU call: reason ``"fmu-crashed"``."""


class FMUHung(SimulationError):
    """An FMU call did not return within the watchdog: reason ``"fmu-hung"``."""


class _Record:
    """The supervisor's view of the child's call record (:mod:`heliostep.cosim.watch`)."""

    def __init__(self, path: Path):
        path.write_bytes(struct.pack(LAYOUT, -1, -1, 0, 0, float("nan")))
        with open(path, "r+b") as handle:
            self._map = mmap.mmap(handle.fileno(), RECORD_BYTES)

    def read(self) -> tuple[int, int, int, float]:
        """(unit index, function index, calls begun, time of the call [s])."""
        unit, function, calls, _, time = struct.unpack_from(LAYOUT, self._map)
        return unit, function, calls, time

    def request_stop(self) -> None:
        struct.pack_into("=q", self._map, STOP_OFFSET, 1)

    def close(self) -> None:
        self._map.close()


class _Forked:
    """A forked child process, seen as :class:`subprocess.Popen` sees one (``poll``, ``wait``, ``kill``)."""

    def __init__(self, pid: int):
        self.pid = pid
        self.returncode: int | None = None

    def poll(self) -> int | None:
        if self.returncode is None:
            pid, status = os.waitpid(self.pid, os.WNOHANG)
            if pid:
                self.returncode = os.waitstatus_to_exitcode(status)
        return self.returncode

    def wait(self) -> int:
        if self.returncode is None:
            self.returncode = os.waitstatus_to_exitcode(os.waitpid(self.pid, 0)[1])
        return self.returncode

    def kill(self) -> None:
        if self.returncode is None:
            os.kill(self.pid, signal.SIGKILL)


def _fork(request: Request, ours: socket.socket, theirs: socket.socket, folder: Path, journal: Journal) -> _Forked:
    """The child forked from this process (everything already imported, the request at hand)."""
    for stream in (sys.stdout, sys.stderr):  # nothing buffered here may be written twice (None: started closed)
        if stream is not None:
            stream.flush()
    pid = os.fork()
    if pid == 0:  # the child: it never returns into the supervisor's code, nor runs its exit handlers
        status = 1
        try:
            ours.close()
            connection = Connection(theirs.detach())
            status = serve(connection, str(folder / "calls"), journal, request, str(folder / "tmp"))
        finally:
            os._exit(status)
    return _Forked(pid)


#: Held while a child of the fork server is started (the starting process's daemon flag is lowered meanwhile).
_STARTING = threading.Lock()


class _Served:
    """A child started by multiprocessing's fork server, seen as :class:`_Forked` (``poll``, ``wait``, ``kill``)."""

    def __init__(self, theirs: socket.socket, folder: Path):
        context = multiprocessing.get_context("forkserver")
        context.set_forkserver_preload(["heliostep.run.supervision.child"])
        connection = Connection(os.dup(theirs.fileno()))
        current = multiprocessing.current_process()
        try:
            self.process = context.Process(
                target=run,
                args=(connection, str(folder / "calls"), str(folder / "rows"), str(folder / "tmp"), os.getpid()),
                daemon=True,
            )
            with _STARTING:  # a Dask worker is a daemonic process, which multiprocessing lets start no child:
                daemonic = current.daemon  # this one ends with it all the same (child.die_with_process)
                current.daemon = False
                try:
                    self.process.start()
                except OSError as exc:  # e.g. its socket's path, in TMPDIR, longer than a Unix socket takes
                    raise RunFailure(
                        f"the fork server could not start the supervised child: {exc.strerror or exc} (its socket "
                        f"goes in the temporary folder {tempfile.gettempdir()}, TMPDIR)"
                    ) from None
                finally:
                    current.daemon = daemonic
        finally:
            connection.close()
        self.pid = self.process.pid

    def poll(self) -> int | None:
        return self.process.exitcode

    def wait(self) -> int:
        self.process.join()
        return self.process.exitcode if self.process.exitcode is not None else 1

    def kill(self) -> None:
        if self.process.exitcode is None:
            self.process.kill()


class _Supervisor:
    """One child process running ``request``, its messages dispatched to the run's callbacks."""

    def __init__(
        self,
        request: Request,
        folder: Path,
        callbacks: dict[str, Callable | None],
        watchdog: float,
        start_method: StartMethod,
    ):
        self.request, self.callbacks, self.watchdog = request, callbacks, watchdog
        self.names = list(request.system.fmus)
        self.forked = start_method == "fork"
        width = len(master_columns(request.system))
        try:
            self.record = _Record(folder / "calls")
            if self.forked:  # the forked child inherits the memory
                self.journal = Journal.in_memory(width)
            else:  # the fork server's child maps the file by name
                Journal.create(folder / "rows", width)
                self.journal = Journal(folder / "rows")
            (folder / "tmp").mkdir()
        except OSError as exc:  # the temporary folder is full or read-only: named, it is not --out
            raise RunFailure(
                f"the supervised child's files could not be made in {folder.parent} (the temporary folder, "
                f"TMPDIR): {exc.strerror or exc}"
            ) from None
        self.received = 0  # ("blocks", ...) messages received
        ours, theirs = socket.socketpair()
        for end in (ours, theirs):  # room for a few blocks of solver steps: neither side waits on the other
            for option in (socket.SO_SNDBUF, socket.SO_RCVBUF):
                end.setsockopt(socket.SOL_SOCKET, option, SOCKET_BUFFER)
        try:
            if self.forked:
                self.process: _Forked | _Served = _fork(request, ours, theirs, folder, self.journal)
            else:
                self.process = _Served(theirs, folder)
        finally:
            theirs.close()
        self.connection = Connection(ours.detach())
        self.time = request.start  # the latest time of a row received [s]
        self.outcome: tuple[str, object] | None = None
        self.ended = False  # the child's end of the socket is closed
        self.started = False  # the child has its request: from now on the watchdog runs

    def run(self, should_stop: Callable[[], bool] | None) -> tuple[str, object]:
        """Serve the child until it reports its outcome or fails; returns (kind, payload)."""
        if not self.forked:  # a forked child has it already
            self.connection.send_bytes(pickle.dumps(self.request, protocol=pickle.HIGHEST_PROTOCOL))
        calls, progressed, stop_asked = -1, clock.monotonic(), None
        while self.outcome is None:
            received = self._receive()  # for at most about _POLL
            now = clock.monotonic()
            if self.outcome is not None:
                break
            if received:
                progressed = now
            elif self.ended or self.process.poll() is not None and not self.connection.poll(0):
                self.process.wait()  # dead: its journal is final
                self._take_unsent()
                return "crashed", self._crash_message()
            current = self.record.read()[2]  # FMI calls begun
            if current != calls:
                calls, progressed = current, now
            elif now - progressed > (self.watchdog if self.started else max(self.watchdog, STARTUP_LIMIT)):
                return self._killed("hung", self._hang_message)
            if stop_asked is None and should_stop is not None and should_stop():
                self.record.request_stop()
                stop_asked = now
            elif stop_asked is not None and now - stop_asked > STOP_GRACE:
                return self._killed("stuck", self._where)
        return self.outcome

    def _killed(self, kind: str, message: Callable[[], str]) -> tuple[str, object]:
        """The child killed (hung, or not stopping when asked) and every row it sent before
        received: (``kind``, ``message()``)."""
        self.process.kill()
        self.process.wait()
        while not self.ended and self.outcome is None and self._receive():
            pass
        if self.outcome is None:
            self._take_unsent()
        return kind, message()

    def _take_unsent(self) -> None:
        """The rows the dead child computed and did not send (its journal's) to the monitor and the sink."""
        solution, trace = self.journal.unsent(self.received)
        show = self.callbacks.get("solution")
        if show is not None and len(solution):
            show(solution)
        if len(trace):
            self._dispatch([trace], None)

    @property
    def fmu_time(self) -> float:
        """The FMU's last time: that of the last FMI call begun, or of the last row where none says one [s]."""
        time = self.record.read()[3]
        return float(time) if np.isfinite(time) and time >= self.time else self.time

    def _receive(self) -> bool:
        """Dispatch the messages waiting (up to :data:`_POLL` for the first); True if any came."""
        if self.ended or not self.connection.poll(_POLL):
            return False
        deadline = clock.monotonic() + _POLL
        while self.outcome is None and clock.monotonic() < deadline:
            try:
                kind, payload = self.connection.recv()
            except (EOFError, OSError):  # the child is gone without an outcome
                self.ended = True
                return False
            if kind == "blocks":
                self.received += 1
                self._dispatch(*payload)
            elif kind == "progress" and self.callbacks.get("progress") is not None:
                self.callbacks["progress"](payload)  # type: ignore[misc]
            elif kind == "started":
                self.started = True
            elif kind != "progress":
                self.outcome = (kind, payload)
            if self.outcome is not None:
                break
            if not self.connection.poll(0):
                break
        return True

    def _dispatch(self, blocks: list[np.ndarray], totals: object) -> None:
        """Blocks of trace rows to the sink, then the monitor's totals to the monitor (the outcome
        set when the sink cannot take them)."""
        store = self.callbacks.get("rows")
        for block in blocks:
            if store is not None:
                try:
                    store(block)
                except (HeliostepError, RuntimeError) as exc:  # the sink cannot take them (disk full ...)
                    self.outcome = ("sink", f"{exc}")
                    return
            if len(block):
                self.time = max(self.time, float(block[-1, 0]))
        take_totals = self.callbacks.get("totals")
        if take_totals is not None and totals is not None:
            take_totals(totals)

    def _where(self) -> str:
        unit, function, calls, time = self.record.read()
        if calls == 0 or not 0 <= unit < len(self.names):
            return "before any FMU call"
        name = self.names[unit]
        info = self.request.system.fmus[name]
        model, call = info.model_name, called_function(function, info.kind)
        at = f" at t = {time:.9g} s" if np.isfinite(time) else ""
        return f"in {call} of FMU instance '{name}' (model {model}){at}"

    def _crash_message(self) -> str:
        status = self.process.wait()
        if status < 0:
            how = f"was killed by {signal.Signals(-status).name}"
        else:
            how = f"exited with status {status} without finishing (an FMU calling exit()?)"
        return f"the simulation process {how} {self._where()}; {self._kept()}"

    def _hang_message(self) -> str:
        return (
            f"the FMU hangs: no FMI call begun for {self.watchdog:g} s (the watchdog) {self._where()}; "
            f"its process was killed; {self._kept()}"
        )

    def _kept(self) -> str:
        return f"the trace keeps the rows up to t = {self.time:.9g} s"

    def close(self) -> None:
        if self.process.poll() is None:
            self.process.kill()
        self.process.wait()
        self.connection.close()
        self.record.close()
        self.journal.close()


def simulate_supervised(
    system: CoSimulation,
    start_time: float,
    stop_time: float,
    output_times,
    solver: SolverOptions | None = None,
    progress: Callable[[float], None] | None = None,
    monitor: SupervisedMonitor | None = None,
    should_stop: Callable[[], bool] | None = None,
    sink: Callable[[np.ndarray], None] | None = None,
    sink_rows: int = 4096,
    watchdog: float = DEFAULT_WATCHDOG,
    start_method: StartMethod = "fork",
) -> MasterResult:
    """``system.simulate(...)`` in a supervised child process (see the module docstring).

    ``monitor`` takes the rows in the child (a copy of it: forked, or pickled to the fork server's
    child) and this one takes that one's totals as they come. ``watchdog`` [s]: how long no FMI call
    may begin before the FMU counts as hung. ``start_method``: ``"fork"`` (this process runs one
    thread) or ``"forkserver"`` (it runs threads: a Dask worker).
    """
    if not watchdog > 0:
        raise InputError(f"watchdog: {watchdog!r} s; expected a positive number of seconds")
    if start_method not in ("fork", "forkserver"):
        raise InputError(f"start_method: {start_method!r}; expected 'fork' or 'forkserver'")
    library_path()  # the compiled kernel built (once) here, not in the child's time
    request = Request(
        system,
        start_time,
        stop_time,
        np.asarray(output_times, dtype=float),
        solver or SolverOptions(),
        sink_rows,
        sink=sink is not None,
        monitor=monitor,
        progress=progress is not None,
    )
    columns = master_columns(system)
    # the child hands over each block of rows its master stores; stored here again, they reach the
    # sink in the very blocks the master would hand it in-process (and none is lost in the child)
    rows = RowBuffer(columns, sink, sink_rows) if sink is not None else None
    totals = monitor.take_totals if monitor is not None else None
    callbacks: dict[str, Callable | None] = {"rows": rows.store if rows is not None else None, "totals": totals}
    callbacks.update(solution=monitor, progress=progress)
    folder = Path(tempfile.mkdtemp(prefix="heliostep-child-"))
    supervisor = None
    try:
        supervisor = _Supervisor(request, folder, callbacks, watchdog, start_method)
        kind, payload = supervisor.run(should_stop)
        failed_at = supervisor.fmu_time if kind in ("crashed", "hung") else supervisor.time
    finally:
        if supervisor is not None:
            supervisor.close()
        shutil.rmtree(folder, ignore_errors=True)
    if rows is not None:
        try:
            rows.flush()  # the rows received, on every outcome
        except (HeliostepError, RuntimeError) as exc:
            kind, payload = "sink", f"{exc}"
    return _outcome(kind, payload, failed_at, columns)


def master_columns(system: CoSimulation) -> list[str]:
    """The master's trace columns: time, its inputs, every FMU's traced outputs."""
    columns = ["time"] + [item.name for item in system.inputs]
    return columns + [f"{name}.{output}" for name, info in system.fmus.items() for output in info.traced_outputs]


def _outcome(kind: str, payload, reached: float, columns: list[str]) -> MasterResult:
    """The child's outcome as the master's: its result, or the error it (or its end) amounts to."""
    empty = pd.DataFrame({c: np.zeros(0) for c in columns})
    if kind == "done":
        return payload
    if kind == "failed":
        raise SimulationError(
            payload["message"], payload["trace"], payload["statistics"], payload["reason"], payload["time"]
        )
    if kind == "input":
        raise InputError(payload)
    if kind == "error":
        raise RuntimeError(f"the supervised simulation failed:\n{payload}")
    if kind == "sink":
        raise SimulationError(f"{payload} (at t = {reached:.9g} s)", empty, {"supervised": True}, "failed", reached)
    if kind == "crashed":
        raise FMUCrashed(str(payload), empty, {"supervised": True}, "fmu-crashed", reached)
    if kind == "hung":
        raise FMUHung(str(payload), empty, {"supervised": True}, "fmu-hung", reached)
    if kind != "stuck":
        raise RuntimeError(f"the simulation process said {kind!r}, which its supervisor does not know")
    raise SimulationError(  # asked to stop, it did not
        f"interrupted; the simulation did not stop within {STOP_GRACE:g} s {payload} and was killed",
        empty,
        {"supervised": True},
        "interrupted",
        reached,
    )
