"""One co-simulation in a process of its own, for a supervisor: :func:`serve`.

The supervisor (:mod:`heliostep.run.supervision.supervisor`) forks and calls :func:`serve` with the request, or
has multiprocessing's fork server start :func:`run` with a connected socket and the path of its call
record (:mod:`heliostep.cosim.watch`) and sends it one request: a pickled :class:`Request` (the
:class:`~heliostep.cosim.master.CoSimulation`, its time span, output grid, solver options and the
monitor). The child says ``("started", None)``, simulates it (its monitor, a
:class:`SupervisedMonitor`, takes every solution row here) and streams, as it goes,
``("blocks", ([block, ...], totals))``: the trace rows for the supervisor's row sink and the monitor's
:meth:`~SupervisedMonitor.totals` after them (so a crash keeps the figures of the rows sent), and
``("progress", t)``, keeping the rows computed and not yet sent in a journal its supervisor maps
(:mod:`heliostep.run.supervision.journal`) and reads when the child dies; it ends with exactly one
of ``("done", MasterResult)``, ``("failed", SimulationError's fields)``, ``("input", message)`` or
``("error", traceback)``. Only the supervisor
decides that a run succeeded: a child that ends without saying ``done`` (a crash, an FMU calling
``exit``) has failed, whatever its exit status. The supervisor reports a crash itself, so the child
prints no fault dump of its own (:mod:`faulthandler` off).

The child ignores SIGINT, SIGTERM and SIGHUP (a terminal sends them to the whole process group):
the supervisor asks it to stop through the call record, or kills it. It stops on its own when
its parent is gone: at its next safe point, and at once when an FMU hangs or the parent was killed
(SIGKILL) — the kernel kills it then (Linux: ``prctl(PR_SET_PDEATHSIG, SIGKILL)``,
:func:`die_with_supervisor`; elsewhere a thread that polls the parent's pid every
:data:`PARENT_POLL` s and ends the process). A child of the fork server also ends when its
supervisor does (:func:`die_with_process`: the fork server lives on while any of its children holds
the supervisor's end of its pipe), so a hung FMU's process never outlives its supervisor.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import faulthandler
import os
import pickle
import select
import signal
import sys
import tempfile
import threading
import time as clock
import traceback
from dataclasses import dataclass
from multiprocessing.connection import Connection
from typing import Any, Protocol

import numpy as np

from heliostep.cosim import watch
from heliostep.cosim.kernel import Kernel
from heliostep.cosim.master import CoSimulation, SimulationError, SolutionMonitor
from heliostep.cosim.rows import RowBuffer
from heliostep.cosim.signals import SolverOptions
from heliostep.errors import InputError
from heliostep.run.supervision.allocator import restore_dynamic_heap
from heliostep.run.supervision.journal import Journal

__all__ = [
    "BLOCK_ROWS",
    "PARENT_POLL",
    "PROGRESS_INTERVAL",
    "SEND_INTERVAL",
    "Request",
    "SupervisedMonitor",
    "die_with_process",
    "die_with_supervisor",
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

#: The trace rows and the monitor's totals go to the supervisor together, at most this often
#: [s of wall time] (one message, the blocks' order kept) or once :data:`BLOCK_ROWS` trace rows
#: are held (one message per block would cost more than the simulation on a busy machine).
SEND_INTERVAL = 0.05

#: The child's kernel hands its rows to the master once it holds this many trace rows (rows at
#: output times, ``Kernel.OUTPUTS_PER_BLOCK``; the rows of internal steps, for the monitor only, in
#: the kernel's full blocks), and its outbox sends them once it holds this many (or after
#: :data:`SEND_INTERVAL`), so the supervisor's trace follows the run closely. A crash or a hang of an
#: FMU loses none of them: those not yet sent are in the journal.
BLOCK_ROWS = 128


class SupervisedMonitor(SolutionMonitor, Protocol):
    """A monitor that runs in the child: it takes the rows there, and its figures so far
    (:meth:`totals`, picklable) are taken by the supervisor's monitor (:meth:`take_totals`)."""

    def totals(self) -> Any:
        """The figures of the rows taken so far (what changed since the totals before)."""
        ...

    def take_totals(self, totals: Any) -> None:
        """The child's monitor's :meth:`totals`, each in turn, in place of rows."""
        ...


class _Outbox:
    """The master's trace row blocks, in order, sent together with the monitor's totals as
    ``("blocks", ([block, ...], totals))``; until sent, they and the rows the monitor took are
    kept in the journal too."""

    def __init__(self, connection: Connection, monitor: SupervisedMonitor | None, journal: Journal):
        self.connection, self.monitor, self.journal = connection, monitor, journal
        self.items: list[np.ndarray] = []
        self.trace_rows = 0  # trace rows among the items
        self.sent = clock.monotonic()

    def add(self, block: np.ndarray) -> None:
        """Trace rows of the master's (its sink)."""
        block = np.array(block, dtype=float)  # a copy: the master reuses its buffers
        self.items.append(block)
        self.trace_rows += len(block)
        kept = self.journal.keep_trace(block)
        if not kept or self.trace_rows >= BLOCK_ROWS or clock.monotonic() - self.sent >= SEND_INTERVAL:
            self.flush()

    def show(self, rows: np.ndarray) -> None:
        """Solution rows for the monitor (the master's monitor): kept, then taken (or taken and sent at once)."""
        assert self.monitor is not None
        if self.journal.keep_solution(rows):
            self.monitor(rows)
        else:  # no room: the monitor's totals carry them now
            self.monitor(rows)
            self.flush()

    def flush(self) -> None:
        totals = self.monitor.totals() if self.monitor is not None else None
        self.connection.send(("blocks", (self.items, totals)))
        self.journal.sent()
        self.items, self.trace_rows = [], 0
        self.sent = clock.monotonic()


@dataclass
class Request:
    """What the child simulates: ``system.simulate(start, stop, output_times, solver, ...)``,
    with a sink of ``sink_rows`` rows per block, ``monitor`` and a progress report where asked."""

    system: CoSimulation
    start: float
    stop: float
    output_times: np.ndarray
    solver: SolverOptions
    sink_rows: int = 4096
    sink: bool = True
    monitor: SupervisedMonitor | None = None
    progress: bool = False


def run(
    connection: Connection, record: str, journal: str, tmpdir: str | None = None, supervisor: int | None = None
) -> int:
    """Serve one request read from ``connection`` (:func:`serve`; a child started by multiprocessing's fork
    server for the process ``supervisor``).
    A supervisor gone (its end of the socket closed: e.g. a Dask worker closed with its cluster) ends
    the run with one line on stderr and exit status 1: there is no one left to stream to."""
    try:
        return serve(connection, record, journal, None, tmpdir, supervisor)
    except (BrokenPipeError, ConnectionResetError, EOFError) as exc:
        why = getattr(exc, "strerror", None) or "connection closed"
        print(f"heliostep: a supervised run ends: its supervisor is gone ({why})", file=sys.stderr)
        return 1


def serve(
    connection: Connection,
    record: str,
    journal: Journal | str,
    request: Request | None = None,
    tmpdir: str | None = None,
    supervisor: int | None = None,
) -> int:
    """Simulate ``request`` (or the one read from ``connection``) and stream it on ``connection``,
    noting FMU calls in the file ``record`` and keeping the rows not yet sent in ``journal`` (the
    :class:`~heliostep.run.supervision.journal.Journal` a forked child inherits, or the file to map);
    ``tmpdir``: the temporary folder to use; ``supervisor``: the supervising process where it is not this
    one's parent. Returns the exit status."""
    faulthandler.disable()  # a crash in an FMU is the supervisor's to report, without a dump here
    for number in (signal.SIGINT, signal.SIGTERM, getattr(signal, "SIGHUP", None)):
        if number is not None:
            signal.signal(number, signal.SIG_IGN)
    if tmpdir is not None:
        os.environ["TMPDIR"] = tempfile.tempdir = tmpdir
    restore_dynamic_heap()  # a Dask worker's MALLOC_TRIM_THRESHOLD_, inherited: see heliostep.run.supervision.allocator
    parent = os.getppid()
    die_with_supervisor(parent)
    if supervisor is not None and supervisor != parent:
        die_with_process(supervisor)
    watch.attach(record)
    rows = journal if isinstance(journal, Journal) else Journal(journal)
    Kernel.block_buffer = rows.kernel_block  # the kernel's rows not yet handed over, readable after a crash
    RowBuffer.flush_interval = 0.0  # every block the master stores goes out (in the outbox)
    Kernel.OUTPUTS_PER_BLOCK = BLOCK_ROWS  # and the kernel hands its trace rows over in small blocks
    if request is None:
        request = pickle.loads(connection.recv_bytes())
    connection.send(("started", None))
    outbox = _Outbox(connection, request.monitor, rows)
    try:
        result = _simulate(request, outbox, parent)
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


def die_with_process(pid: int) -> None:
    """End this process as soon as the process ``pid`` ends, even while an FMU call never returns: a
    daemon thread waits for it (a pidfd where the OS has them, else polling every :data:`PARENT_POLL` s)."""

    def wait() -> None:
        try:
            handle = os.pidfd_open(pid)
        except (AttributeError, OSError):  # no pidfd here (or the process is gone already)
            while _exists(pid):
                clock.sleep(PARENT_POLL)
        else:
            select.select([handle], [], [])  # readable once the process has ended
        os._exit(1)

    threading.Thread(target=wait, name="heliostep-watch-supervisor", daemon=True).start()


def _exists(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


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
        monitor=outbox.show if request.monitor is not None else None,
        should_stop=should_stop,
        sink=outbox.add if request.sink else None,
        sink_rows=request.sink_rows,
    )
