"""FMI 3.0 Model Exchange instances: fmpy's ``FMU3Model`` behind :class:`ModelExchangeInstance`'s API.

:class:`ModelExchange3Instance` is an FMI 3.0 Model Exchange instance that the master, the
connections and the compiled kernel use exactly like an FMI 2.0 one. Its ``component`` is an
adapter (``c/fmi3_adapter.c``, compiled once like the kernel and cached by content) holding the
``fmi3Instance`` and its fmi3* functions, and its fmi2-shaped functions (``fmi2GetReal`` ...) are
the adapter's: ``fmi3GetFloat64``/``SetFloat64``/``GetInt32``/``SetInt32`` with their extra
``nValues``, ``fmi3GetBoolean``/``SetBoolean`` with C ``bool`` values converted, the calls of the
same shape passed through, and every other variable (an array element, Float32, Int8 ... UInt64,
an enumeration) reached through the adapter's slot table as a double
(:mod:`heliostep.cosim.fmi3_types`). So one kernel (``kernel.c``) runs FMI 2.0 and 3.0 FMUs in one
system. Off the hot path (event-time connections, parameters, String and Binary) each type is got
and set with its own fmi3 function (:func:`~heliostep.cosim.fmi3_types.typed_access`).
The life cycle is FMI 3.0's own: ``fmi3EnterInitializationMode`` (tolerance, start and stop time),
``fmi3EnterEventMode``, the ``fmi3UpdateDiscreteStates`` iteration (``discreteStatesNeedUpdate``,
``terminateSimulation``, ``nominalsOfContinuousStatesChanged``, ``valuesOfContinuousStatesChanged``,
``nextEventTimeDefined``/``nextEventTime``), ``fmi3EnterContinuousTimeMode``,
``fmi3CompletedIntegratorStep``, ``fmi3Terminate``, ``fmi3FreeInstance``. Each instance logs
through its own ``instanceEnvironment`` into :class:`ModelExchangeInstance`'s message buffer.
"""

from __future__ import annotations

import ctypes
import os
from collections import deque
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from heliostep.cosim import watch
from heliostep.cosim.fmi import (
    _CALLS,
    _HOT_CALLS,
    EventResult,
    FMIError,
    FMUInfo,
    ModelExchangeInstance,
    _by_environment,
    _dispatch_log,
    _environment_ids,
    _extract,
)
from heliostep.cosim.fmi3_types import TYPED_CALLS, slot_table, typed_access
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


_STATUS_ONLY = ctypes.CFUNCTYPE(ctypes.c_int, ctypes.c_void_p)
_B = ctypes.c_bool
_B_P = ctypes.POINTER(ctypes.c_bool)
_CALLS3 = {
    **{
        name: _STATUS_ONLY
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


class ModelExchange3Instance(ModelExchangeInstance):
    """One instance of an FMI 3.0 Model Exchange FMU (see the module docstring); same API as
    :class:`ModelExchangeInstance`, the FMI calls FMI 3.0's."""

    def __init__(
        self,
        info: FMUInfo,
        instance_name: str,
        parameters: Mapping[str, object] | None = None,
        logging: bool = False,
        index: int = -1,
    ):
        from fmpy.fmi3 import FMU3Model

        self.info, self.name, self.index = info, instance_name, index
        self.messages: deque[str] = deque(maxlen=50)
        self.n_states, self.n_event_indicators = len(info.states), info.n_event_indicators
        self.time, self.mode, self._model = float("nan"), "freed", None
        self._environment = next(_environment_ids)
        _by_environment[self._environment] = self
        self._stop_time = None
        try:
            watch.note(index, "loading the binary", self.time)
            self._model = FMU3Model(
                guid=info.guid,
                unzipDirectory=_extract(info.path),
                modelIdentifier=info.model_identifier,
                instanceName=instance_name,
            )
            watch.note(index, "fmi3InstantiateModelExchange", self.time)
            self._instance = self._model.fmi3InstantiateModelExchange(
                instance_name.encode(),
                info.guid.encode(),
                (os.path.join(self._model.unzipDirectory, "resources") + os.path.sep).encode(),
                False,
                logging,
                ctypes.c_void_p(self._environment),
                _logger3(),
            )
            if not self._instance:
                raise RuntimeError("fmi3InstantiateModelExchange returned NULL")
        except Exception as exc:
            if self._model is not None:
                try:
                    self._model.freeLibrary()
                except Exception:  # noqa: BLE001
                    pass
            self._model = None
            raise FMIError("fmi3InstantiateModelExchange", instance_name, f"failure ({exc})", self.messages) from None
        self.mode = "instantiated"
        self._bind()
        self._x, self._dx = np.zeros(self.n_states), np.zeros(self.n_states)
        self._x_ptr, self._dx_ptr = self._pointer(self._x), self._pointer(self._dx)
        if parameters:
            try:
                self.set_parameters(parameters)
            except BaseException:
                self.free()
                raise

    def _bind(self) -> None:
        """The adapter (its handle is the component the kernel and the hot path pass) and the calls."""
        assert self._model is not None
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
        prototypes = {**_CALLS, **_HOT_CALLS}
        self._functions = {name: prototypes[name](self._addresses[name]) for name in _ADAPTED}
        self._hot = {name: self._functions[name] for name in _HOT_CALLS}
        self._fmi3 = {name: prototype((name, dll)) for name, prototype in {**_CALLS3, **TYPED_CALLS}.items()}

    def function_address(self, name: str) -> int:
        """The address of the fmi2-shaped function ``name`` (the adapter's, taking :attr:`component`)."""
        if self._model is None:
            raise FMIError(name, self.name, "no instance (freed, library unloaded)", (), self.time)
        return self._addresses[name]

    def _call3(self, function: str, *args: Any) -> int:
        """Call the FMI 3.0 function ``function`` on the fmi3Instance; raise :class:`FMIError` on error or fatal."""
        if self._model is None:
            raise FMIError(function, self.name, "no instance (freed, library unloaded)", (), self.time)
        if self.messages:
            self.messages.clear()
        watch.note(self.index, function, self.time)
        status = self._fmi3[function](self._instance, *args)
        if status > 1:
            raise self.status_error(function, status)
        return status

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
    def setup_experiment(self, start_time: float = 0.0, tolerance: float | None = None) -> None:
        """FMI 3.0 has no fmi2SetupExperiment: start time and tolerance go to fmi3EnterInitializationMode."""
        self.time, self._tolerance = start_time, tolerance

    def enter_initialization_mode(self) -> None:
        tolerance = getattr(self, "_tolerance", None)
        self._call3("fmi3EnterInitializationMode", tolerance is not None, tolerance or 0.0, self.time, False, 0.0)
        self.mode = "initialization"

    def exit_initialization_mode(self) -> None:
        self._call3("fmi3ExitInitializationMode")
        self.mode = "event"

    def enter_event_mode(self) -> None:
        self._call3("fmi3EnterEventMode")
        self.mode = "event"

    def update_discrete_states(self, max_iterations: int = 100, first: None = None) -> EventResult:
        """Iterate fmi3UpdateDiscreteStates until ``discreteStatesNeedUpdate`` is false (or it terminates)."""
        need, terminate, nominals, values, defined = (ctypes.c_bool() for _ in range(5))
        next_time = ctypes.c_double()
        changed = nominals_changed = False
        for _ in range(max_iterations):
            self._call3(
                "fmi3UpdateDiscreteStates",
                ctypes.byref(need),
                ctypes.byref(terminate),
                ctypes.byref(nominals),
                ctypes.byref(values),
                ctypes.byref(defined),
                ctypes.byref(next_time),
            )
            changed |= values.value
            nominals_changed |= nominals.value
            if terminate.value or not need.value:
                break
        else:
            raise FMIError(
                "fmi3UpdateDiscreteStates",
                self.name,
                f"no fixed point after {max_iterations} event iterations",
                self.messages,
                self.time,
            )
        return EventResult(
            terminate=terminate.value,
            states_changed=changed,
            next_event_time=next_time.value if defined.value else None,
            nominals_changed=nominals_changed,
        )

    def enter_continuous_time_mode(self) -> None:
        self._call3("fmi3EnterContinuousTimeMode")
        self.mode = "continuous"

    def completed_integrator_step(self) -> tuple[bool, bool]:
        """Returns (enter event mode, terminate simulation)."""
        enter, terminate = ctypes.c_bool(), ctypes.c_bool()
        self._call3("fmi3CompletedIntegratorStep", True, ctypes.byref(enter), ctypes.byref(terminate))
        return enter.value, terminate.value

    def get_nominals(self) -> np.ndarray:
        out = np.ones(self.n_states)
        if self.n_states:
            self._call3("fmi3GetNominalsOfContinuousStates", out.ctypes.data, self.n_states)
        return out

    def terminate(self) -> None:
        self._call3("fmi3Terminate")
        self.mode = "terminated"

    def reset(self) -> None:
        self._call3("fmi3Reset")
        self.mode = "instantiated"

    def free(self) -> None:
        """fmi3FreeInstance (not after fmi3Fatal) and unload the binary (safe to call twice)."""
        if self._model is not None:
            model, self._model = self._model, None
            self._hot = {name: self._freed(name) for name in _HOT_CALLS}
            try:
                if self.mode != "fatal":
                    watch.note(self.index, "fmi3FreeInstance", self.time)
                    model.fmi3FreeInstance(self._instance)
            finally:
                self.mode = "freed"
                self._component = None
                model.freeLibrary()
