"""The command's standard streams: closed descriptors filled, and a standard output that fails kept from
deciding the exit status (:func:`guard_standard_streams`).

A command's results are its files; what it prints on standard output is a report of them. A full device or a
reader that went away (``| head``) must therefore neither turn written results into a failure nor a failure
into a success: the first failing write or flush is said once on standard error, the rest of the output goes
to the null device, and the exit status stays what the command decided.
"""

from __future__ import annotations

import os
import sys
from typing import TextIO

__all__ = ["GuardedOutput", "guard_standard_streams"]


def guard_standard_streams() -> None:
    """Fill closed standard descriptors with the null device and guard standard output (:class:`GuardedOutput`)."""
    for descriptor in (0, 1, 2):  # no file the command opens may take 0, 1 or 2 (an FMU's printf writes there)
        try:
            os.fstat(descriptor)
        except OSError:
            null = os.open(os.devnull, os.O_RDWR)
            if null != descriptor:
                os.dup2(null, descriptor)
                os.close(null)
    for name, descriptor in (("stdout", 1), ("stderr", 2)):  # None where started closed: the null device now
        if getattr(sys, name) is None:
            setattr(sys, name, open(descriptor, "w", closefd=False, errors="backslashreplace"))
    if not isinstance(sys.stdout, GuardedOutput):
        sys.stdout = GuardedOutput(sys.stdout)


class GuardedOutput:
    """A text stream whose write and flush never raise :class:`OSError`: on the first failure the stream's
    descriptor is pointed at the null device (what is buffered goes there too) and standard error says so."""

    def __init__(self, stream: TextIO):
        self._stream = stream

    def write(self, text: str) -> int:
        try:
            return self._stream.write(text)
        except OSError as exc:
            self._lost(exc)
            return len(text)

    def flush(self) -> None:
        try:
            self._stream.flush()
        except OSError as exc:
            self._lost(exc)
            self._stream.flush()  # what was buffered, into the null device now

    def _lost(self, exc: OSError) -> None:
        null = os.open(os.devnull, os.O_WRONLY)
        try:
            os.dup2(null, self._stream.fileno())
        finally:
            os.close(null)
        if sys.stderr is not None:
            reason = exc.strerror or type(exc).__name__
            message = f"heliostep: warning: standard output failed ({reason}); what was printed there is lost"
            print(message, file=sys.stderr, flush=True)

    def __getattr__(self, name: str):
        return getattr(self._stream, name)
