"""Supervised simulation: the master runs in a child process, so an FMU cannot take the run down.

:func:`simulate_supervised` is :meth:`CoSimulation.simulate <heliostep.cosim.master.CoSimulation.simulate>`
with the same arguments and results, but the simulation runs in a child process (forked, forked by a
fork server, or a new interpreter: :data:`START`, ``$HELIOSTEP_SUPERVISED_START`` ``fork``,
``server``, ``exec`` or ``auto``; :mod:`heliostep.cosim.child`) that streams its rows back over a
socket: the supervisor
(this process) feeds them to the run's row sink and monitor as they come, exactly as the master
would in-process, so the figures and the trace are the same bit for bit.

When an FMU crashes the child (a segmentation fault, ``abort()``, the FMU calling ``exit`` —
even ``exit(0)``: only the child's explicit ``done`` is a success), the supervisor raises
:class:`FMUCrashed`; when no FMI call begins for ``watchdog`` seconds (an FMU looping inside a
call), it kills the child and raises :class:`FMUHung`. Both are
:class:`~heliostep.cosim.master.SimulationError` with ``reason`` ``"fmu-crashed"`` /
``"fmu-hung"`` and name the FMU instance, its model and the FMI call it was in, read from the
call record the child keeps in a file both processes map (:mod:`heliostep.cosim.watch`). The
rows received until then are in the sink: the run keeps its trace so far, marked.

A stop request (``should_stop``) is passed to the child, which stops at its next safe point;
a child that does not stop within :data:`STOP_GRACE` (an FMU stuck in a call) is killed, and the
run ends as interrupted with the rows so far. The child's temporary files (its unpacked FMUs,
the call record) are in a folder of the supervisor's, removed on every path.
"""

from __future__ import annotations

import logging
import mmap
import os
import pickle
import shutil
import signal
import socket
import struct
import subprocess
import sys
import tempfile
import threading
import time as clock
from collections.abc import Callable
from multiprocessing.connection import Connection
from pathlib import Path

import numpy as np
import pandas as pd

from heliostep.cosim import CoSimulation, MasterResult, SimulationError, SolverOptions, fork_server
from heliostep.cosim import master as master_module
from heliostep.cosim.child import Request, serve
from heliostep.cosim.figures import FigureSpec
from heliostep.cosim.kernel import library_path
from heliostep.cosim.rows import RowBuffer
from heliostep.cosim.watch import LAYOUT, RECORD_BYTES, STOP_OFFSET, called_function
from heliostep.errors import HeliostepError, InputError

__all__ = ["DEFAULT_WATCHDOG", "STOP_GRACE", "FMUCrashed", "FMUHung", "simulate_supervised"]

logger = logging.getLogger(__name__)

#: Seconds without a new FMI call (and without a message from the child) before the supervisor
#: declares the FMU hung (a model evaluation takes microseconds to milliseconds).
DEFAULT_WATCHDOG = 60.0

#: How the child is started: ``"fork"`` (nothing to import again, about a millisecond),
#: ``"server"`` (forked by this process's fork server, :mod:`heliostep.cosim.fork_server`: a
#: single-threaded helper with the child's modules imported, started once, lazily; a few
#: milliseconds per child), ``"exec"`` (a new interpreter, ``python -m heliostep.cosim.child``:
#: about half a second of imports) or ``"auto"``: fork where the OS can and this process runs one
#: thread only (a fork copies one thread, and any lock another one held: a Dask worker's threads),
#: else the fork server where the OS has one (AF_UNIX sockets passing descriptors, fork), else exec.
#: A fork server that cannot be started (twice) leaves exec. ``$HELIOSTEP_SUPERVISED_START`` chooses.
START = os.environ.get("HELIOSTEP_SUPERVISED_START") or "auto"


def _start_method() -> str:
    if START != "auto":
        return START
    if hasattr(os, "fork") and threading.active_count() == 1:
        return "fork"
    return "server" if fork_server.AVAILABLE else "exec"


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


def _fork(request: Request, ours: socket.socket, theirs: socket.socket, folder: Path) -> _Forked:
    """The child forked from this process (everything already imported, the request at hand)."""
    sys.stdout.flush()  # nothing buffered here may be written twice
    sys.stderr.flush()
    pid = os.fork()
    if pid == 0:  # the child: it never returns into the supervisor's code, nor runs its exit handlers
        status = 1
        try:
            ours.close()
            status = serve(Connection(theirs.detach()), str(folder / "calls"), request, str(folder / "tmp"))
        finally:
            os._exit(status)
    return _Forked(pid)


def _execute(theirs: socket.socket, folder: Path) -> subprocess.Popen:
    """The child as a new interpreter (``python -m heliostep.cosim.child``), its TMPDIR the supervisor's folder."""
    environment = {**os.environ, "TMPDIR": str(folder / "tmp")}
    command = [sys.executable, "-m", "heliostep.cosim.child", str(theirs.fileno()), str(folder / "calls")]
    return subprocess.Popen(command, pass_fds=[theirs.fileno()], env=environment, stdin=subprocess.DEVNULL)


class _Supervisor:
    """One child process running ``request``, its messages dispatched to the run's callbacks."""

    def __init__(self, request: Request, folder: Path, callbacks: dict[str, Callable | None], watchdog: float):
        self.request, self.callbacks, self.watchdog = request, callbacks, watchdog
        self.names = list(request.system.fmus)
        self.record = _Record(folder / "calls")
        (folder / "tmp").mkdir()
        ours, theirs = socket.socketpair()
        for end in (ours, theirs):  # room for a few blocks of solver steps: neither side waits on the other
            for option in (socket.SO_SNDBUF, socket.SO_RCVBUF):
                end.setsockopt(socket.SOL_SOCKET, option, SOCKET_BUFFER)
        method = _start_method()
        self.forked = method == "fork"
        try:
            process: _Forked | fork_server.Served | subprocess.Popen | None = None
            if self.forked:
                process = _fork(request, ours, theirs, folder)
            elif method == "server":  # None: no fork server could start
                process = fork_server.spawn(theirs, str(folder / "calls"), str(folder / "tmp"))
            self.process = process if process is not None else _execute(theirs, folder)
        finally:
            theirs.close()
        self.connection = Connection(ours.detach())
        self.time = request.start  # the latest time of a row received [s]
        self.outcome: tuple[str, object] | None = None
        self.ended = False  # the child's end of the socket is closed
        self.started = False  # the child has its request: from now on the watchdog runs

    def run(
        self, should_stop: Callable[[], bool] | None, meanwhile: Callable[[], None] | None = None
    ) -> tuple[str, object]:
        """Serve the child until it reports its outcome or fails; returns (kind, payload).

        ``meanwhile()`` is called once, when the child has its request and before any of its
        messages is served (the child simulates meanwhile; its messages wait in the socket). An
        exception from it is logged as a warning, and the run goes on: the rows are not lost for it.
        """
        if not self.forked:  # a forked child has it already
            self.connection.send_bytes(pickle.dumps(self.request, protocol=pickle.HIGHEST_PROTOCOL))
        if meanwhile is not None:
            try:
                meanwhile()
            except Exception:
                logger.warning("%r failed while the child simulated; the run goes on", meanwhile, exc_info=True)
        calls, progressed, stop_asked = -1, clock.monotonic(), None
        while self.outcome is None:
            received = self._receive()  # for at most about _POLL
            now = clock.monotonic()
            if self.outcome is not None:
                break
            if received:
                progressed = now
            elif self.ended or self.process.poll() is not None and not self.connection.poll(0):
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
        return kind, message()

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
                for item, block in payload:
                    if not self._dispatch(item, block):
                        break
            elif kind == "progress" and self.callbacks.get("progress") is not None:
                self.callbacks["progress"](payload)  # type: ignore[misc]
            elif kind == "figures" and self.callbacks.get("figures") is not None:
                self.callbacks["figures"](payload)  # type: ignore[misc]
            elif kind == "started":
                self.started = True
            elif kind != "progress":
                self.outcome = (kind, payload)
            if self.outcome is not None:
                break
            if not self.connection.poll(0):
                break
        return True

    def _dispatch(self, kind: str, block: np.ndarray) -> bool:
        """A block of rows to the sink (``"rows"``) or the monitor (``"solution"``); False (and the
        outcome set) when the sink cannot take it."""
        callback = self.callbacks.get(kind)
        if callback is None:
            return True
        try:
            callback(block)
        except (HeliostepError, RuntimeError) as exc:  # the sink cannot take them (disk full ...)
            self.outcome = ("sink", f"{exc}")
            return False
        if kind == "rows" and len(block):
            self.time = max(self.time, float(block[-1, 0]))
        return True

    def _where(self) -> str:
        unit, function, calls, time = self.record.read()
        if calls == 0 or not 0 <= unit < len(self.names):
            return "before any FMU call"
        name = self.names[unit]
        info = self.request.system.fmus[name]
        model, call = info.model_name, called_function(function, info.fmi_version)
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


def simulate_supervised(
    system: CoSimulation,
    start_time: float,
    stop_time: float,
    output_times,
    solver: SolverOptions | None = None,
    progress: Callable[[float], None] | None = None,
    monitor: Callable[[np.ndarray], None] | None = None,
    should_stop: Callable[[], bool] | None = None,
    sink: Callable[[np.ndarray], None] | None = None,
    sink_rows: int = 4096,
    watchdog: float = DEFAULT_WATCHDOG,
    meanwhile: Callable[[], None] | None = None,
) -> MasterResult:
    """``system.simulate(...)`` in a supervised child process (see the module docstring).

    ``watchdog`` [s]: how long no FMI call may begin before the FMU counts as hung. ``meanwhile``:
    work of the caller's own done in this process while the child starts simulating (called once,
    before the first of the child's rows is served; an exception from it is logged as a warning
    and does not end the run), e.g. the trace writers' first-use costs
    (:func:`heliostep.results.trace.files.warm_up_writers`).
    """
    if not watchdog > 0:
        raise InputError(f"watchdog: {watchdog!r} s; expected a positive number of seconds")
    library_path()  # the compiled kernel built (once) here, not in the child's time
    request = Request(
        system,
        start_time,
        stop_time,
        np.asarray(output_times, dtype=float),
        solver or SolverOptions(),
        sink_rows,
        sink=sink is not None,
        monitor=monitor is not None,
        progress=progress is not None,
        figures=_figure_spec(monitor),
    )
    columns = master_columns(system)
    # the child hands over each block of rows its master stores; stored here again, they reach the
    # sink in the very blocks the master would hand it in-process (and none is lost in the child)
    rows = RowBuffer(columns, sink, sink_rows) if sink is not None else None
    callbacks = {"rows": rows.store if rows is not None else None, "solution": monitor, "progress": progress}
    if request.figures is not None:  # the kernel's figures, sent once by the child's master
        callbacks["figures"] = getattr(monitor, "take_kernel_figures")  # noqa: B009
    folder = Path(tempfile.mkdtemp(prefix="heliostep-child-"))
    supervisor = None
    try:
        supervisor = _Supervisor(request, folder, callbacks, watchdog)
        kind, payload = supervisor.run(should_stop, meanwhile)
    finally:
        if supervisor is not None:
            supervisor.close()
        shutil.rmtree(folder, ignore_errors=True)
    if rows is not None:
        try:
            rows.flush()  # the rows received, on every outcome
        except (HeliostepError, RuntimeError) as exc:
            kind, payload = "sink", f"{exc}"
    return _outcome(kind, payload, supervisor.time, columns)


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


def _figure_spec(monitor: Callable[[np.ndarray], None] | None) -> FigureSpec | None:
    """What the child's kernel accumulates for ``monitor`` (None: every solution row sent back), as in-process."""
    spec = getattr(monitor, "kernel_figures", None)
    if not master_module.KERNEL_FIGURES or spec is None or not hasattr(monitor, "take_kernel_figures"):
        return None
    fields = spec()
    return None if fields is None else FigureSpec(**fields)
