"""Dask's preload for the workers of heliostep's own local cluster: they leave the terminal's stop signals to
the command.

A Ctrl+C at the terminal reaches the whole process group: the command, its local cluster's worker processes
and their supervised runs. The command stops the sweep (or band) itself, keeping what finished; a worker that
took the signal too would die mid-case with a traceback, and its nanny would start it again while the cluster
closes. The cluster's processes are started with these signals blocked (:func:`held_while_starting`, the mask
is inherited), so one that comes while a worker starts waits; this preload then ignores them there for good.
Light on purpose (the standard library only): it runs as each worker process starts, before any task.
"""

from __future__ import annotations

import contextlib
import logging
import signal
from collections.abc import Callable, Iterator
from multiprocessing import resource_tracker

#: This module's name, as :class:`distributed.LocalCluster`'s ``preload`` takes it.
PRELOAD = __name__

#: The signals a terminal sends to its whole foreground process group.
TERMINAL_SIGNALS = frozenset(getattr(signal, name) for name in ("SIGINT", "SIGHUP") if hasattr(signal, name))


def dask_setup(worker) -> None:
    """Dask's preload hook, called in the worker process's main thread as it starts: the terminal's signals
    ignored there, and so in every process it starts (the disposition is inherited), then unblocked (one that
    came while it started is discarded)."""
    for signum in TERMINAL_SIGNALS:
        signal.signal(signum, signal.SIG_IGN)
    signal.pthread_sigmask(signal.SIG_UNBLOCK, TERMINAL_SIGNALS)


def dask_teardown(worker) -> None:
    """Dask's preload hook, called as the worker closes, before it removes its work folder: from then on what
    distributed says there is about the closing (a folder the command already removed, a scheduler gone)."""
    silence_distributed_logs()


def silence_distributed_logs() -> bool:
    """distributed's stream handlers (where its loggers' records end) pass only CRITICAL records from now on,
    in this process; run on each worker (and here) as heliostep's own local cluster closes."""
    for handler in logging.getLogger("distributed").handlers:
        if isinstance(handler, logging.StreamHandler):
            handler.setLevel(logging.CRITICAL)
    return True


@contextlib.contextmanager
def held_while_starting() -> Iterator[Callable[[], None]]:
    """Within the block, the terminal's signals are blocked in this thread and every thread and process it
    starts (the cluster's event loop, its worker processes); the block's ``release()`` (or its end)
    unblocks them here, and a signal that came meanwhile is then taken by this process's handler."""
    # multiprocessing's resource tracker, started by the first process a thread starts, unblocks SIGINT in
    # that thread (resource_tracker.ensure_running); started here before the block, it is left alone
    resource_tracker.ensure_running()
    previous = signal.pthread_sigmask(signal.SIG_BLOCK, TERMINAL_SIGNALS)
    released = False

    def release() -> None:
        nonlocal released
        if not released:
            released = True
            signal.pthread_sigmask(signal.SIG_SETMASK, previous)

    try:
        yield release
    finally:
        release()
