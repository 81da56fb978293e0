"""FMI 3.0 Model Exchange instances (fmpy's ``FMU3Model`` loads the binary), a sibling of FMI 2.0's.

The fmi2-shaped calls the master and the compiled kernel make on every instance go to an adapter
(``c/fmi3_adapter.c``, compiled once and cached by content) holding the ``fmi3Instance`` and its fmi3
functions: Float64, Int32 and Boolean with their own calls, every other variable (an array element,
Float32, Int8 ... UInt64, an enumeration) through the adapter's slot table as a double
(:mod:`~heliostep.cosim.fmi3_types`). Off the hot path each type is got and set with its own fmi3 function.
"""

from __future__ import annotations

import ctypes
import functools
import os
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from heliostep.cosim.fmi3_types import TYPED_CALLS, slot_table, typed_access
from heliostep.cosim.instance import HOT_CALLS, SHAPED_CALLS, STATUS_ONLY, ModelExchangeBase, _dispatch_log
from heliostep.cosim.kinds import life_cycle
from heliostep.cosim.libraries import compiled_library

ADAPTER_SOURCE = Path(__file__).resolve().parent / "c" / "fmi3_adapter.c"

#: fmi2-shaped name -> the adapter's function
_ADAPTED = {
    "fmi2SetTime": "hs3_set_time",
    "fmi2SetContinuousStates": "hs3_set_states",
    "fmi2GetContinuousStates": "hs3_get_states",
    "fmi2GetDerivatives": "hs3_get_derivatives",
    "fmi2GetEventIndicators": "hs3_get_event_indicators",
    "fmi2GetReal": "hs3_get_real",
    "fmi2SetReal": "hs3_set_real",
    "fmi2GetInteger": "hs3_get_integer",
    "fmi2SetInteger": "hs3_set_integer",
    "fmi2GetBoolean": "hs3_get_boolean",
    "fmi2SetBoolean": "hs3_set_boolean",
}

#: the adapter's fields, in the order of hs3_adapter: (field, fmi3 function)
_ADAPTER_FIELDS = (
    ("set_time", "fmi3SetTime"),
    ("set_states", "fmi3SetContinuousStates"),
    ("get_states", "fmi3GetContinuousStates"),
    ("get_derivatives", "fmi3GetContinuousStateDerivatives"),
    ("get_event_indicators", "fmi3GetEventIndicators"),
    ("get_float64", "fmi3GetFloat64"),
    ("set_float64", "fmi3SetFloat64"),
    ("get_int32", "fmi3GetInt32"),
    ("set_int32", "fmi3SetInt32"),
    ("get_boolean", "fmi3GetBoolean"),
    ("set_boolean", "fmi3SetBoolean"),
)


#: the typed functions of the adapter's slots, by type code (fmi3_adapter.c, fmi3_types.FMI3_TYPES)
_SLOT_TYPES = (
    "Float64",
    "Float32",
    "Int8",
    "UInt8",
    "Int16",
    "UInt16",
    "Int32",
    "UInt32",
    "Int64",
    "UInt64",
    "Boolean",
)


#: hs3_adapter's fields (fmi3_adapter.c), in its order
_ADAPTER_STRUCT: list[tuple[str, Any]] = (
    [("instance", ctypes.c_void_p)]
    + [(field, ctypes.c_void_p) for field, _ in _ADAPTER_FIELDS]
    + [("slot_base", ctypes.c_uint), ("n_slots", ctypes.c_size_t), ("slots", ctypes.c_void_p)]
    + [("scratch", ctypes.c_void_p)]
    + [("typed_get", ctypes.c_void_p * len(_SLOT_TYPES)), ("typed_set", ctypes.c_void_p * len(_SLOT_TYPES))]
)


class _Adapter(ctypes.Structure):
    _fields_ = _ADAPTER_STRUCT


_B = ctypes.c_bool
_B_P = ctypes.POINTER(ctypes.c_bool)
_CALLS3 = {
    **{
        name: STATUS_ONLY
        for name in (
            "fmi3ExitInitializationMode",
            "fmi3EnterEventMode",
            "fmi3EnterContinuousTimeMode",
            "fmi3Terminate",
            "fmi3Reset",
        )
    },
    "fmi3EnterInitializationMode": ctypes.CFUNCTYPE(
        ctypes.c_int, ctypes.c_void_p, _B, ctypes.c_double, ctypes.c_double, _B, ctypes.c_double
    ),
    "fmi3UpdateDiscreteStates": ctypes.CFUNCTYPE(
        ctypes.c_int, ctypes.c_void_p, _B_P, _B_P, _B_P, _B_P, _B_P, ctypes.POINTER(ctypes.c_double)
    ),
    "fmi3CompletedIntegratorStep": ctypes.CFUNCTYPE(ctypes.c_int, ctypes.c_void_p, _B, _B_P, _B_P),
    "fmi3GetNominalsOfContinuousStates": ctypes.CFUNCTYPE(
        ctypes.c_int, ctypes.c_void_p, ctypes.c_void_p, ctypes.c_size_t
    ),
}

_log_callback = None
_adapter_library: ctypes.CDLL | None = None


def _dispatch_log3(environment, status, category, message) -> None:
    """The fmi3LogMessageCallback of every instance: routed by ``instanceEnvironment``."""
    _dispatch_log(environment, b"", status, category, message)


def _logger3():
    global _log_callback
    if _log_callback is None:
        from fmpy.fmi3 import fmi3LogMessageCallback

        _log_callback = fmi3LogMessageCallback(_dispatch_log3)
    return _log_callback


def adapter_library() -> ctypes.CDLL:
    """The compiled FMI 3.0 adapter, built at first use beside the kernel, loaded once per process."""
    global _adapter_library
    if _adapter_library is None:
        path = compiled_library("heliostep_fmi3_adapter", "the FMI 3.0 adapter", [ADAPTER_SOURCE], ["-std=c99"])
        _adapter_library = ctypes.CDLL(str(path))
    return _adapter_library


class ModelExchange3Instance(ModelExchangeBase):
    """One instance of an FMI 3.0 Model Exchange FMU (see :class:`~heliostep.cosim.instance.ModelExchangeBase`)."""

    _life = life_cycle("3.0")

    def _fmpy_model(self) -> Any:
        from fmpy.fmi3 import FMU3Model

        return FMU3Model

    def _instantiate(self, logging: bool) -> None:
        self._handle = self._instance = self._model.fmi3InstantiateModelExchange(
            self.name.encode(),
            self.info.guid.encode(),
            (os.path.join(self._model.unzipDirectory, "resources") + os.path.sep).encode(),
            False,
            logging,
            ctypes.c_void_p(self._environment),
            _logger3(),
        )
        if not self._instance:
            raise RuntimeError("fmi3InstantiateModelExchange returned NULL")

    def _bind(self) -> None:
        """The adapter (its address is the component the fmi2-shaped calls take) and the calls."""
        dll, library = self._model.dll, adapter_library()

        def address(name: str) -> int | None:
            return ctypes.cast(dll[name], ctypes.c_void_p).value

        base, self._slots = slot_table(self.info.variables)
        largest = max((v.size for v in self.info.variables.values()), default=1)
        self._scratch = np.zeros(max(largest, 1), dtype=np.float64)  # 8 bytes a value, for any type
        self._adapter = _Adapter(
            self._instance,
            *[address(name) for _, name in _ADAPTER_FIELDS],
            base,
            len(self._slots),
            self._slots.ctypes.data,
            self._scratch.ctypes.data,
            (ctypes.c_void_p * len(_SLOT_TYPES))(*[address(f"fmi3Get{t}") for t in _SLOT_TYPES]),
            (ctypes.c_void_p * len(_SLOT_TYPES))(*[address(f"fmi3Set{t}") for t in _SLOT_TYPES]),
        )
        self._component = ctypes.addressof(self._adapter)
        self._addresses = {
            name: ctypes.cast(library[shim], ctypes.c_void_p).value or 0 for name, shim in _ADAPTED.items()
        }
        self._hot = {name: HOT_CALLS[name](self._addresses[name]) for name in HOT_CALLS}
        self._functions = {
            **{
                name: functools.partial(SHAPED_CALLS[name](self._addresses[name]), self._component) for name in _ADAPTED
            },
            **{
                name: functools.partial(prototype((name, dll)), self._instance)
                for name, prototype in {**_CALLS3, **TYPED_CALLS}.items()
            },
        }

    def _address(self, name: str) -> int:
        return self._addresses[name]

    # ------------------------------------------------------------------ variables of any type
    def _typed(self, kind: str, names: list[str]) -> tuple[Callable[[], None], Callable[[], None], np.ndarray]:
        """(get, set, buffer) of variables of one type, with FMI 3.0's function of their type
        (:func:`~heliostep.cosim.fmi3_types.typed_access`; ``kind`` is the master's type name)."""
        return typed_access(self, names)

    def set_parameters(self, values: Mapping[str, object]) -> None:
        """Set parameters by name (an array's elements by theirs, ``p[2]``), each FMI 3.0 type with its
        own fmi3Set function: Float32/64, Int8 ... UInt64, Boolean, String, Binary, Enumeration."""
        for items in self._parameters_by_type(values, lambda variable: variable.fmi3_type).values():
            _, put, buffer = typed_access(self, [name for name, _, _ in items])
            buffer[:] = [value for _, _, value in items]
            put()

    def set_string(self, value_references, values) -> None:
        by_reference = {v.value_reference: v.name for v in self.info.variables.values() if v.fmi3_type == "String"}
        _, put, buffer = typed_access(self, [by_reference[r] for r in value_references])
        buffer[:] = list(values)
        put()

    # ------------------------------------------------------------------ life cycle
    def enter_initialization_mode(self) -> None:
        """fmi3EnterInitializationMode with the tolerance and start time (FMI 3.0 has no SetupExperiment)."""
        tolerance = self._tolerance
        args = (tolerance is not None, tolerance or 0.0, self.time, False, 0.0)
        self._into(self._life.enter_initialization_mode, "initialization", *args)

    def _update_once(self, iteration: int, first: Any) -> tuple[bool, bool, bool, bool, float | None]:
        """One fmi3UpdateDiscreteStates."""
        need, terminate, nominals, values, defined = (ctypes.c_bool() for _ in range(5))
        next_time = ctypes.c_double()
        self._call(
            "fmi3UpdateDiscreteStates",
            ctypes.byref(need),
            ctypes.byref(terminate),
            ctypes.byref(nominals),
            ctypes.byref(values),
            ctypes.byref(defined),
            ctypes.byref(next_time),
        )
        return need.value, terminate.value, values.value, nominals.value, next_time.value if defined.value else None
