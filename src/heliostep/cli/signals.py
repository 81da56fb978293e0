"""Stopping a command cleanly on SIGINT (Ctrl+C), SIGTERM and SIGHUP, and at once on a second one.

The first signal is recorded, so a long computation ends at its next safe point with its results
written; a second raises :class:`ForcedStop` (every ``finally`` runs); a third ends the process.
Exit status: 128 + the signal number.

Details: docs/running.md, ``heliostep.cli.signals``.
"""

from __future__ import annotations

import os
import signal
import sys
import threading
from collections.abc import Iterator
from contextlib import contextmanager

__all__ = [
    "STOP_SIGNALS",
    "ForcedStop",
    "StopRequest",
    "StartingUp",
    "StopSignal",
    "exit_status",
    "signals_end_the_command",
    "stop_requests",
]

#: The signals that stop a command (SIGHUP where the platform has it, handled as SIGTERM).
STOP_SIGNALS = tuple(getattr(signal, name) for name in ("SIGINT", "SIGTERM", "SIGHUP") if hasattr(signal, name))


class _SignalExit(BaseException):
    """Leaving because of the stop signal ``signum``: exit status 128 + ``signum``."""

    def __init__(self, signum: int):
        super().__init__(signum)
        self.signum = signum

    @property
    def exit_status(self) -> int:
        return exit_status(self.signum)


class StopSignal(_SignalExit):
    """A stop signal outside a command's own handling (e.g. while the modules are imported)."""

    def __str__(self) -> str:
        return signal.Signals(self.signum).name


class _LenientStream:
    """A text stream that passes writes to ``stream`` and drops those that fail (a hung-up terminal)."""

    def __init__(self, stream):
        self._stream = stream

    def write(self, text: str) -> int:
        try:
            return self._stream.write(text)
        except (OSError, ValueError):
            return len(text)

    def flush(self) -> None:
        try:
            self._stream.flush()
        except (OSError, ValueError):
            pass

    def __getattr__(self, name: str):
        return getattr(self._stream, name)


def _after_hangup(signum: int) -> None:
    """After SIGHUP the terminal may be gone: stdout and stderr drop what they cannot write."""
    if getattr(signal, "SIGHUP", None) == signum:
        for name in ("stdout", "stderr"):
            stream = getattr(sys, name)
            if stream is not None and not isinstance(stream, _LenientStream):
                setattr(sys, name, _LenientStream(stream))


class StartingUp:
    """What a stop signal does within :func:`signals_end_the_command`: while ``at_once`` (the
    modules being imported: nothing written yet, and an exception raised there may be swallowed
    by an import's own ``except``), one line and ``os._exit``; then :class:`StopSignal`."""

    def __init__(self) -> None:
        self.at_once = True
        self.command = "heliostep"


def signals_until_exit() -> None:
    """From now until the process ends, a stop signal no longer interrupts the exit: the first is noted and
    the exit goes on with the command's status, a second ends the process at once (128 + its number).

    The installed command calls it before the command runs, so :func:`signals_end_the_command` restores
    these handlers, not Python's, when the command returns; ignored signals stay ignored."""
    taken: list[int] = []

    def handler(signum, frame):
        _after_hangup(signum)
        if taken:
            os._exit(exit_status(signum))
        taken.append(signum)

    _install_stop_handler(handler)


@contextmanager
def signals_end_the_command() -> Iterator[StartingUp]:
    """Within the block, a stop signal ends the command: at once with one line while
    ``StartingUp.at_once``, else by raising :class:`StopSignal` (a ``BaseException``). The
    previous handlers are restored on leaving; ignored signals stay ignored; outside the main
    thread nothing is installed."""
    state = StartingUp()
    if threading.current_thread() is not threading.main_thread():
        yield state
        return

    def handler(signum, frame):
        _after_hangup(signum)
        if state.at_once:
            try:
                sys.stderr.write(f"{state.command}: stopped by {signal.Signals(signum).name} while starting\n")
                sys.stderr.flush()
            finally:
                os._exit(exit_status(signum))
        raise StopSignal(signum)

    with _handling_stop_signals(handler), _raised_again_after_callbacks(StopSignal):
        yield state


@contextmanager
def _handling_stop_signals(handler) -> Iterator[None]:
    """Within the block, ``handler`` handles the stop signals that are not ignored (an ignored one,
    e.g. SIGINT of a background job, stays so); the previous handlers are restored on leaving."""
    previous: dict = {}
    try:
        previous = _install_stop_handler(handler)
        yield
    finally:
        for sig, old in previous.items():
            signal.signal(sig, old)


def _install_stop_handler(handler) -> dict:
    """``handler`` for every stop signal that is not ignored; the handlers it replaced, by signal."""
    return {sig: signal.signal(sig, handler) for sig in STOP_SIGNALS if signal.getsignal(sig) is not signal.SIG_IGN}


@contextmanager
def _raised_again_after_callbacks(kind: type[BaseException] | tuple[type[BaseException], ...]) -> Iterator[None]:
    """Within the block, an exception of ``kind`` that a signal handler raised inside a weakref
    callback or ``__del__`` (where Python only prints "Exception ignored") is raised again 1 ms
    later by SIGALRM, outside the callback (Unix only; raising it inside the hook would run a
    handler at once, inside the hook)."""
    swallowed: list[BaseException] = []
    previous_alarm: dict = {}
    previous_hook = sys.unraisablehook

    def again(signum, frame):
        if swallowed:
            raise swallowed.pop()

    def unraisable(hook_args):
        if isinstance(hook_args.exc_value, kind) and hasattr(signal, "setitimer"):
            swallowed[:] = [hook_args.exc_value]
            if "handler" not in previous_alarm:
                previous_alarm["handler"] = signal.signal(signal.SIGALRM, again)
            signal.setitimer(signal.ITIMER_REAL, 1e-3)
            return
        previous_hook(hook_args)

    sys.unraisablehook = unraisable
    try:
        yield
    finally:
        sys.unraisablehook = previous_hook
        if previous_alarm:
            signal.setitimer(signal.ITIMER_REAL, 0.0)
            signal.signal(signal.SIGALRM, previous_alarm["handler"])


class ForcedStop(_SignalExit):
    """A second stop signal: leave now (``finally`` blocks run), exit status 128 + ``signum``."""

    def __str__(self) -> str:
        return f"{signal.Signals(self.signum).name} a second time"


class StopRequest:
    """Set by the first stop signal; ``signum`` says which, ``count`` how many came."""

    def __init__(self) -> None:
        self._event = threading.Event()
        self.signum: int | None = None
        self.count = 0

    def is_set(self) -> bool:
        return self._event.is_set()

    def set(self, signum: int) -> None:
        if self.signum is None:
            self.signum = signum
        self._event.set()

    @property
    def name(self) -> str:
        return signal.Signals(self.signum).name if self.signum is not None else ""

    @property
    def exit_status(self) -> int:
        return exit_status(self.signum or signal.SIGINT)


def exit_status(signum: int) -> int:
    """The shell's convention for a process ended by a signal: 128 + its number."""
    return 128 + int(signum)


@contextmanager
def stop_requests(raise_exception: type[BaseException] | None = None) -> Iterator[StopRequest]:
    """Within the block, SIGINT, SIGTERM and SIGHUP set the returned :class:`StopRequest`; a
    second one raises :class:`ForcedStop`, a third ends the process.

    With ``raise_exception``, the handler also raises it (for code that waits in Python, e.g. a
    Dask client). Outside the main thread nothing is installed; an ignored signal stays ignored.
    """
    request = StopRequest()
    if threading.current_thread() is not threading.main_thread():
        yield request
        return

    def handler(signum, frame):
        _after_hangup(signum)  # (SIGHUP: the terminal may be gone)
        request.count += 1
        request.set(signum)
        if request.count == 1:
            if raise_exception is not None:
                raise raise_exception(signum)
        elif request.count == 2:
            raise ForcedStop(signum)
        else:  # a third: no more clean-up
            os._exit(exit_status(signum))

    kinds = (ForcedStop,) if raise_exception is None else (ForcedStop, raise_exception)
    with _handling_stop_signals(handler), _raised_again_after_callbacks(kinds):
        yield request
