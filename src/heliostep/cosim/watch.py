"""Where this process's FMU calls are, for a supervisor in another process.

Before every FMI call (the compiled kernel's and the Python ones alike) a supervised child
(:mod:`heliostep.run.supervision`) stores, in a record both processes map (:class:`Record`, kernel.h
``hs_where``; :data:`LAYOUT` for :mod:`struct`), the instance's index, the function's index in
:data:`FUNCTIONS`, the time and a running count of the calls begun; the supervisor reads the count to
tell a hang from a long run, and writes ``stop`` to ask the child to stop at its next safe point.
Without :func:`attach` nothing is recorded.
"""

from __future__ import annotations

import ctypes
import mmap
import os
from pathlib import Path

from heliostep.cosim.kinds import KINDS, Kind

__all__ = [
    "FUNCTIONS",
    "KERNEL_FUNCTIONS",
    "LAYOUT",
    "RECORD_BYTES",
    "STOP_OFFSET",
    "Record",
    "attach",
    "called_function",
    "note",
    "record_address",
    "stop_requested",
]

#: The FMI functions the compiled kernel calls, in the order of kernel.h's ``F_*`` codes.
KERNEL_FUNCTIONS = (
    "fmi2SetTime",
    "fmi2SetContinuousStates",
    "fmi2GetReal",
    "fmi2SetReal",
    "fmi2GetDerivatives",
    "fmi2GetEventIndicators",
    "fmi2GetInteger",
    "fmi2GetBoolean",
)
#: Every FMI function a run calls (the kernel's first): the record's function index is a position here.
FUNCTIONS = (
    *KERNEL_FUNCTIONS,
    "loading the binary",
    *dict.fromkeys(name for kind in KINDS if kind.life is not None for name in kind.life),
    "fmi2SetupExperiment",
    "fmi2GetContinuousStates",
    "fmi2SetInteger",
    "fmi2SetBoolean",
    "fmi2GetString",
    "fmi2SetString",
    # FMI 3.0's typed setters (heliostep.cosim.fmi3_types); its fmi2-shaped calls are noted by their fmi2 names
    *(f"fmi3Set{t}" for t in ("Float32", "Int8", "UInt8", "Int16", "UInt16", "UInt32", "Int64", "UInt64")),
)
_INDEX = {name: k for k, name in enumerate(FUNCTIONS)}


class Record(ctypes.Structure):
    """kernel.h ``hs_where``."""

    _fields_ = [
        ("unit", ctypes.c_int64),
        ("function", ctypes.c_int64),
        ("calls", ctypes.c_int64),
        ("stop", ctypes.c_int64),
        ("time", ctypes.c_double),
    ]


#: The record's layout for :mod:`struct` (native byte order, no padding: four int64 and a double).
LAYOUT = "=4qd"
RECORD_BYTES = ctypes.sizeof(Record)
#: The byte offset of the stop request.
STOP_OFFSET = Record.stop.offset

_map: mmap.mmap | None = None
_record: Record | None = None


def attach(path: str | Path) -> None:
    """Record this process's FMU calls into the file ``path`` (:data:`RECORD_BYTES` bytes, made by the supervisor)."""
    global _map, _record
    descriptor = os.open(path, os.O_RDWR)
    try:
        _map = mmap.mmap(descriptor, RECORD_BYTES)
    finally:
        os.close(descriptor)
    _record = Record.from_buffer(_map)
    _record.unit, _record.function = -1, -1


def record_address() -> int | None:
    """The address of the record (for ``hs_kernel.where``), None when not attached."""
    return ctypes.addressof(_record) if _record is not None else None


def note(unit: int, function: str, time: float = float("nan")) -> None:
    """Record that instance ``unit`` (its index in the master's order) begins ``function`` at ``time`` [s]."""
    record = _record
    if record is not None:
        record.unit = unit
        record.function = _INDEX.get(function, -1)
        record.time = time
        record.calls += 1


def stop_requested() -> bool:
    """True when the supervisor asked this process to stop (False when not attached)."""
    return _record is not None and _record.stop != 0


def called_function(function: int, kind: Kind) -> str:
    """The name of the FMI function at index ``function`` of :data:`FUNCTIONS` for an FMU of ``kind`` (its
    own name for the fmi2-shaped calls), or "an FMI call" for an unknown index."""
    name = FUNCTIONS[function] if 0 <= function < len(FUNCTIONS) else "an FMI call"
    return kind.own_name(name)
