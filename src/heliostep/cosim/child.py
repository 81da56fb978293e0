"""One co-simulation in a process of its own, for a supervisor: forked (:func:`serve`) or executed
(``python -m heliostep.cosim.child``, :func:`main`).

The supervisor (:mod:`heliostep.run.supervised`) forks and calls :func:`serve` with the request,
or starts this module with the number of a connected socket and the path of its call record
(:mod:`heliostep.cosim.watch`) and sends it one request: a pickled :class:`Request` (the
:class:`~heliostep.cosim.master.CoSimulation`, its time span, output grid and solver options).
The child says ``("started", None)``, simulates it
and streams, as it goes, ``("blocks", [(kind, block), ...])`` with ``kind`` ``"rows"`` (trace
rows, for the supervisor's row sink) or ``"solution"`` (for its monitor), and ``("progress",
t)``; it ends with exactly one of ``("done", MasterResult)``, ``("failed", SimulationError's
fields)``, ``("input", message)`` or ``("error", traceback)``. Only the supervisor decides that
a run succeeded: a child that ends without saying ``done`` (a crash, an FMU calling ``exit``)
has failed, whatever its exit status.

The child ignores SIGINT, SIGTERM and SIGHUP (a terminal sends them to the whole process group):
the supervisor asks it to stop through the call record, or kills it. It stops on its own when
the supervisor's process is gone: at its next safe point, and at once when an FMU hangs or the
supervisor was killed (SIGKILL) — the kernel kills it then (Linux: ``prctl(PR_SET_PDEATHSIG,
SIGKILL)``, :func:`die_with_supervisor`; elsewhere a thread that polls the parent's pid every
:data:`PARENT_POLL` s and ends the process), so a hung FMU's process never outlives its supervisor.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import os
import pickle
import signal
import sys
import tempfile
import threading
import time as clock
import traceback
from collections.abc import Callable
from dataclasses import dataclass, fields
from multiprocessing.connection import Connection

import numpy as np

from heliostep.cosim import watch
from heliostep.cosim.allocator import restore_dynamic_heap
from heliostep.cosim.figures import FigureSpec, FigureTotals, KernelFigures
from heliostep.cosim.kernel import Kernel
from heliostep.cosim.master import CoSimulation, SimulationError
from heliostep.cosim.rows import RowBuffer
from heliostep.cosim.signals import SolverOptions
from heliostep.errors import InputError

__all__ = [
    "BLOCK_ROWS",
    "MAX_ROWS_LOST",
    "PARENT_POLL",
    "PROGRESS_INTERVAL",
    "SEND_INTERVAL",
    "Request",
    "die_with_supervisor",
    "main",
    "run",
    "serve",
]

#: [s] how often the thread that watches the supervisor looks at the parent's pid (where the
#: kernel cannot be asked to kill the child with its parent).
PARENT_POLL = 0.2

#: prctl's option asking the kernel for a signal when the parent dies (linux/prctl.h).
_PR_SET_PDEATHSIG = 1

#: Progress reports at most this often [s of wall time].
PROGRESS_INTERVAL = 0.25

#: The rows of the trace and of the solution go to the supervisor together, at most this often
#: [s of wall time] (one message, their blocks and order kept) or once :data:`BLOCK_ROWS` trace
#: rows are held. (One message per block would cost more than the simulation on a busy machine.)
SEND_INTERVAL = 0.05

#: The child's kernel hands its rows to the master once it holds this many trace rows (rows at
#: output times, ``Kernel.OUTPUTS_PER_BLOCK``; 4096 in-process; the rows of internal steps, for
#: the monitor only, still in blocks of 4096), and its outbox sends them once it holds this many (or after
#: :data:`SEND_INTERVAL`): the rows a crash or a hang of an FMU loses are those of the kernel's
#: block not yet handed over and those of the outbox not yet sent, fewer than :data:`MAX_ROWS_LOST`.
BLOCK_ROWS = 128

#: The most trace rows a supervised run loses when its child crashes, hangs or is killed (the
#: rows computed before are in the supervisor; tests/test_supervised.py holds it to this).
MAX_ROWS_LOST = 2 * BLOCK_ROWS


class _Outbox:
    """The master's row blocks, ``(kind, block)`` in order, sent together as ``("blocks", [...])``."""

    def __init__(self, connection: Connection):
        self.connection = connection
        self.items: list[tuple[str, np.ndarray]] = []
        self.trace_rows = 0  # trace rows among the items
        self.sent = clock.monotonic()
        self.after_send: Callable[[], None] | None = None  # called after each message of blocks

    def add(self, kind: str, block: np.ndarray) -> None:
        self.items.append((kind, np.array(block, dtype=float)))  # a copy: the master reuses its buffers
        if kind == "rows":
            self.trace_rows += len(block)
        if self.trace_rows >= BLOCK_ROWS or clock.monotonic() - self.sent >= SEND_INTERVAL:
            self.flush()

    def flush(self) -> None:
        if self.items:
            self.connection.send(("blocks", self.items))
            self.items, self.trace_rows = [], 0
            if self.after_send is not None:
                self.after_send()
        self.sent = clock.monotonic()


@dataclass
class Request:
    """What the child simulates: ``system.simulate(start, stop, output_times, solver, ...)``,
    with a sink of ``sink_rows`` rows per block, a monitor and a progress report where asked."""

    system: CoSimulation
    start: float
    stop: float
    output_times: np.ndarray
    solver: SolverOptions
    sink_rows: int = 4096
    sink: bool = True
    monitor: bool = True
    progress: bool = False
    figures: FigureSpec | None = None  # the monitor's figures accumulated in the kernel, sent at the end


class _FiguresToSupervisor:
    """The child's monitor when the figures are accumulated in its kernel: their totals go to the
    supervisor (``("figures", totals)``, after the rows) instead of every solution row."""

    def __init__(self, spec: FigureSpec, outbox: _Outbox):
        self.spec, self.outbox = spec, outbox
        self.figures: KernelFigures | None = None

    def bind_kernel_figures(self, figures: KernelFigures) -> None:
        """The master's accumulator: its snapshot follows every block of rows sent (a crash keeps them)."""
        self.figures = figures
        self.outbox.after_send = lambda: self.outbox.connection.send(("figures", figures.snapshot()))

    def __call__(self, block: np.ndarray) -> None:
        self.outbox.add("solution", block)

    def kernel_figures(self) -> dict:
        """The spec's fields, as a monitor offers them (the master makes the spec of them)."""
        return {field.name: getattr(self.spec, field.name) for field in fields(self.spec)}

    def take_kernel_figures(self, totals: FigureTotals) -> None:
        self.outbox.after_send = None
        self.outbox.flush()
        self.outbox.connection.send(("figures", totals))


def main(argv: list[str]) -> int:
    """Serve one request read from the socket ``argv[1]`` (a file descriptor), noting FMU calls in ``argv[2]``."""
    return run(Connection(int(argv[1])), argv[2])


def run(connection: Connection, record: str, tmpdir: str | None = None) -> int:
    """Serve one request read from ``connection`` (:func:`serve`; also the fork server's children).
    A supervisor gone (its end of the socket closed: e.g. a Dask worker closed with its cluster) ends
    the run with one line on stderr and exit status 1: there is no one left to stream to."""
    try:
        return serve(connection, record, None, tmpdir)
    except (BrokenPipeError, ConnectionResetError, EOFError) as exc:
        why = getattr(exc, "strerror", None) or "connection closed"
        print(f"heliostep: a supervised run ends: its supervisor is gone ({why})", file=sys.stderr)
        return 1


def serve(connection: Connection, record: str, request: Request | None = None, tmpdir: str | None = None) -> int:
    """Simulate ``request`` (or the one read from ``connection``) and stream it on ``connection``,
    noting FMU calls in the file ``record``; ``tmpdir``: the temporary folder to use (a forked
    child's; an executed one has it in ``TMPDIR``). Returns the exit status."""
    for number in (signal.SIGINT, signal.SIGTERM, getattr(signal, "SIGHUP", None)):
        if number is not None:
            signal.signal(number, signal.SIG_IGN)
    if tmpdir is not None:
        os.environ["TMPDIR"] = tempfile.tempdir = tmpdir
    restore_dynamic_heap()  # a Dask worker's MALLOC_TRIM_THRESHOLD_, inherited: see heliostep.cosim.allocator
    supervisor = os.getppid()
    die_with_supervisor(supervisor)
    watch.attach(record)
    RowBuffer.flush_interval = 0.0  # every block the master stores goes out (in the outbox)
    Kernel.OUTPUTS_PER_BLOCK = BLOCK_ROWS  # and the kernel hands its trace rows over in small blocks
    if request is None:
        request = pickle.loads(connection.recv_bytes())
    connection.send(("started", None))
    outbox = _Outbox(connection)
    try:
        result = _simulate(request, outbox, supervisor)
        result.statistics["peak_rss_mb_child"] = _peak_rss_mb()
        outcome: tuple[str, object] = ("done", result)
    except SimulationError as exc:
        fields = {"message": str(exc), "reason": exc.reason, "time": exc.time, "statistics": exc.statistics}
        outcome = ("failed", {**fields, "trace": exc.trace})
    except InputError as exc:
        outcome = ("input", str(exc))
    except Exception:  # noqa: BLE001 - a bug: the supervisor reports it whole
        outcome = ("error", traceback.format_exc())
    try:
        outbox.flush()
        connection.send(outcome)
        connection.close()
    except OSError:  # the supervisor is gone: nobody to tell
        return 1
    return 0


def die_with_supervisor(supervisor: int) -> None:
    """End this process (SIGKILL) as soon as its parent ``supervisor`` dies, even while an FMU
    call never returns: ``prctl(PR_SET_PDEATHSIG, SIGKILL)`` on Linux, else a daemon thread
    polling the parent's pid (it runs while the FMU's native code does: ctypes calls release the GIL)."""
    if sys.platform.startswith("linux"):
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6", use_errno=True)
        if libc.prctl(_PR_SET_PDEATHSIG, int(signal.SIGKILL), 0, 0, 0) == 0:
            if os.getppid() != supervisor:  # died before the request was made: nobody will signal
                os._exit(1)
            return

    def watch_parent() -> None:
        while os.getppid() == supervisor:
            clock.sleep(PARENT_POLL)
        os._exit(1)

    threading.Thread(target=watch_parent, name="heliostep-watch-supervisor", daemon=True).start()


def _peak_rss_mb() -> float | None:
    """This process's peak resident memory [MB] (None where the OS does not say)."""
    try:
        import resource
    except ImportError:  # not on Windows
        return None
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return round(peak / (1024 * 1024 if sys.platform == "darwin" else 1024), 1)  # bytes on macOS, KiB on Linux


def _simulate(request: Request, outbox: _Outbox, supervisor: int):
    last_report = [0.0]

    def progress(t: float) -> None:
        now = clock.monotonic()
        if now - last_report[0] >= PROGRESS_INTERVAL:
            last_report[0] = now
            outbox.flush()
            outbox.connection.send(("progress", t))

    def should_stop() -> bool:
        return watch.stop_requested() or os.getppid() != supervisor

    return request.system.simulate(
        request.start,
        request.stop,
        request.output_times,
        request.solver,
        progress=progress if request.progress else None,
        monitor=_child_monitor(request, outbox),
        should_stop=should_stop,
        sink=(lambda block: outbox.add("rows", block)) if request.sink else None,
        sink_rows=request.sink_rows,
    )


def _child_monitor(request: Request, outbox: _Outbox):
    """The solution rows to the supervisor, or (with ``request.figures``) the kernel's figures."""
    if not request.monitor:
        return None
    if request.figures is not None:
        return _FiguresToSupervisor(request.figures, outbox)
    return lambda block: outbox.add("solution", block)


if __name__ == "__main__":
    sys.exit(main(sys.argv))
