"""The one module that talks to FMUs: fmpy's FMI 2.0 Model Exchange bindings behind a small API.

Everything FMI goes through here: reading and checking ``modelDescription.xml``
(:func:`read_fmu`), loading the binary (``fmpy.fmi2.FMU2Model``) and every call on an
instance (:class:`ModelExchangeInstance`). There is one error path: any FMI call that
returns a status worse than warning raises :class:`FMIError`, which names the function,
the instance and the messages the FMU logged. The rest of heliostep (master, sequencer,
CLI, plots) never touches ctypes.
"""

from __future__ import annotations

import atexit
import ctypes
import shutil
import tempfile
from collections import deque
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from heliostep.errors import HeliostepError, InputError


class FMIError(HeliostepError):
    """An FMI function returned fmi2Error or fmi2Fatal (or an FMU could not be loaded)."""

    def __init__(self, function: str, instance: str, status: str, messages: Iterable[str] = ()):
        self.function = function
        self.instance = instance
        self.status = status
        self.messages = list(messages)
        detail = f": {' | '.join(self.messages)}" if self.messages else ""
        super().__init__(f"{instance}: {function} returned {status}{detail}")


@dataclass(frozen=True)
class VariableInfo:
    """What the master needs to know of one scalar variable."""

    name: str
    value_reference: int
    type: str
    causality: str
    variability: str
    unit: str = ""
    start: float | None = None
    description: str = ""


@dataclass
class FMUInfo:
    """The parts of an FMU's modelDescription.xml that heliostep uses."""

    path: Path
    model_name: str
    model_identifier: str
    guid: str
    variables: dict[str, VariableInfo]
    states: list[str]
    n_event_indicators: int
    #: output name -> names of the inputs it depends on directly (direct feedthrough)
    output_feedthrough: dict[str, list[str]] = field(default_factory=dict)
    #: whether fmi2CompletedIntegratorStep must be called after each integrator step
    needs_completed_integrator_step: bool = True
    description: object = None  # fmpy's ModelDescription

    def names(self, causality: str) -> list[str]:
        return [v.name for v in self.variables.values() if v.causality == causality]

    @property
    def inputs(self) -> list[str]:
        return self.names("input")

    @property
    def outputs(self) -> list[str]:
        return self.names("output")

    @property
    def parameters(self) -> list[str]:
        return self.names("parameter")

    def variable(self, name: str) -> VariableInfo:
        try:
            return self.variables[name]
        except KeyError:
            raise InputError(f"{self.path}: no variable {name!r} in {self.model_name}; "
                             f"variables: {', '.join(self.variables)}") from None


def _unit(variable) -> str:
    if variable.unit:
        return variable.unit
    declared = getattr(variable, "declaredType", None)
    return getattr(declared, "unit", None) or ""


def read_fmu(path: str | Path) -> FMUInfo:
    """Read and check an FMU: it must be FMI 2.0 with Model Exchange (else :class:`InputError`)."""
    from fmpy import read_model_description

    path = Path(path)
    if not path.is_file():
        raise InputError(f"FMU file not found: {path}")
    try:
        description = read_model_description(str(path), validate=False)
    except Exception as exc:
        raise InputError(f"{path}: not a readable FMU ({exc})") from None
    if description.fmiVersion != "2.0":
        raise InputError(f"{path}: FMI version {description.fmiVersion}; heliostep needs FMI 2.0")
    if description.modelExchange is None:
        raise InputError(f"{path}: the FMU does not support Model Exchange (co-simulation only); "
                         "heliostep integrates Model Exchange FMUs itself")
    variables = {}
    for v in description.modelVariables:
        start = None
        if v.type == "Real" and v.start is not None:
            start = float(v.start)
        variables[v.name] = VariableInfo(
            name=v.name, value_reference=v.valueReference, type=v.type, causality=v.causality,
            variability=v.variability, unit=_unit(v), start=start, description=v.description or "")
    states = [d.variable.derivative.name for d in description.derivatives]
    inputs = {v.name for v in description.modelVariables if v.causality == "input"}
    feedthrough = {}
    for unknown in description.outputs:
        dependencies = unknown.dependencies
        if dependencies is None:  # no dependency information: depends on every input
            names = sorted(inputs)
        else:
            names = [d.name for d in dependencies if d.name in inputs]
        feedthrough[unknown.variable.name] = names
    return FMUInfo(
        path=path, model_name=description.modelName,
        model_identifier=description.modelExchange.modelIdentifier, guid=description.guid,
        variables=variables, states=states,
        n_event_indicators=description.numberOfEventIndicators or 0,
        output_feedthrough=feedthrough, description=description,
        needs_completed_integrator_step=bool(description.modelExchange.needsCompletedIntegratorStep))


_extracted: dict[tuple[str, float], str] = {}
_extract_root = None


def _extract(path: Path) -> str:
    """Unzip an FMU once per process (per file and modification time)."""
    global _extract_root
    from fmpy import extract

    key = (str(path.resolve()), path.stat().st_mtime)
    if key not in _extracted:
        if _extract_root is None:
            _extract_root = tempfile.mkdtemp(prefix="heliostep-fmus-")
            atexit.register(shutil.rmtree, _extract_root, True)
        _extracted[key] = extract(str(path), unzipdir=tempfile.mkdtemp(dir=_extract_root))
    return _extracted[key]


_STATUS = ["fmi2OK", "fmi2Warning", "fmi2Discard", "fmi2Error", "fmi2Fatal", "fmi2Pending"]

#: Prototypes of the calls on the integrator's hot path, taking plain addresses (ints) for
#: arrays: converting an int is much cheaper for ctypes than a typed pointer.
_ARRAY_CALL = ctypes.CFUNCTYPE(ctypes.c_int, ctypes.c_void_p, ctypes.c_void_p, ctypes.c_size_t)
_VALUES_CALL = ctypes.CFUNCTYPE(ctypes.c_int, ctypes.c_void_p, ctypes.c_void_p, ctypes.c_size_t, ctypes.c_void_p)
_TIME_CALL = ctypes.CFUNCTYPE(ctypes.c_int, ctypes.c_void_p, ctypes.c_double)
_HOT_CALLS = {"fmi2SetTime": _TIME_CALL, "fmi2SetContinuousStates": _ARRAY_CALL,
              "fmi2GetContinuousStates": _ARRAY_CALL, "fmi2GetDerivatives": _ARRAY_CALL,
              "fmi2GetEventIndicators": _ARRAY_CALL, "fmi2GetReal": _VALUES_CALL, "fmi2SetReal": _VALUES_CALL}


def address(pointer) -> int:
    """The address of a ctypes pointer (e.g. the data of a SUNDIALS vector) as an int."""
    return ctypes.cast(pointer, ctypes.c_void_p).value or 0


@dataclass(frozen=True)
class EventResult:
    """What an event iteration told the master."""

    terminate: bool = False
    states_changed: bool = False
    next_event_time: float | None = None


class ModelExchangeInstance:
    """One instance of an FMI 2.0 Model Exchange FMU.

    Parameters
    ----------
    info : FMUInfo
        The FMU, from :func:`read_fmu`.
    instance_name : str
        Name used in log messages and errors.
    parameters : mapping of str to float, optional
        Parameter values set right after instantiation; an unknown name raises
        :class:`InputError` listing the valid names.
    """

    def __init__(self, info: FMUInfo, instance_name: str,
                 parameters: Mapping[str, float] | None = None, logging: bool = False):
        from fmpy import calloc, free
        from fmpy.fmi2 import (
            FMU2Model,
            fmi2CallbackAllocateMemoryTYPE,
            fmi2CallbackFreeMemoryTYPE,
            fmi2CallbackFunctions,
            fmi2CallbackLoggerTYPE,
        )

        self.info = info
        self.name = instance_name
        self.messages: deque[str] = deque(maxlen=50)
        self.n_states = len(info.states)
        self.n_event_indicators = info.n_event_indicators
        self._model = None
        self._callbacks = fmi2CallbackFunctions()
        self._callbacks.logger = fmi2CallbackLoggerTYPE(self._log)
        self._callbacks.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
        self._callbacks.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
        try:
            from fmpy.logging import addLoggerProxy
            addLoggerProxy(ctypes.byref(self._callbacks))
        except Exception:  # the proxy only formats printf-style arguments  # noqa: BLE001
            pass
        try:
            self._model = FMU2Model(guid=info.guid, unzipDirectory=_extract(info.path),
                                    modelIdentifier=info.model_identifier, instanceName=instance_name)
            self._model.instantiate(callbacks=self._callbacks, loggingOn=logging)
        except Exception as exc:
            self._model = None
            raise FMIError("fmi2Instantiate", instance_name, f"failure ({exc})", self.messages) from None
        self._component = self._model.component
        self._functions = self._model._functions
        self._hot = {name: prototype((name, self._model.dll)) for name, prototype in _HOT_CALLS.items()}
        # buffers with cached pointers for the calls on the integrator's hot path
        self._x, self._dx = np.zeros(self.n_states), np.zeros(self.n_states)
        self._x_ptr, self._dx_ptr = self._pointer(self._x), self._pointer(self._dx)
        if parameters:
            self.set_parameters(parameters)

    # ------------------------------------------------------------------ the error path
    def _log(self, env, instance, status, category, message) -> None:
        text = message.decode("utf-8", "replace") if isinstance(message, bytes) else str(message)
        self.messages.append(text)

    def _call(self, function: str, *args):
        """Call the FMI function ``function``; raise :class:`FMIError` on error or fatal.

        The raw ctypes function from fmpy's table of loaded functions is called directly
        (fmpy's per-call wrapper costs more than the model evaluation itself).
        """
        if self._model is None:
            raise FMIError(function, self.name, "no instance (freed)")
        status = self._functions[function](self._component, *args)
        if status > 1:  # worse than fmi2Warning
            label = _STATUS[status] if 0 <= status < len(_STATUS) else str(status)
            raise FMIError(function, self.name, label, self.messages)
        if self.messages:
            self.messages.clear()
        return status

    @staticmethod
    def _pointer(array: np.ndarray):
        return array.ctypes.data_as(ctypes.POINTER(ctypes.c_double))

    @staticmethod
    def _vrs(value_references: Iterable[int]):
        from fmpy.fmi2 import fmi2ValueReference

        refs = list(value_references)
        return (fmi2ValueReference * len(refs))(*refs), len(refs)

    def _check(self, function: str, status: int) -> None:
        """The error path of the hot calls (same as :meth:`_call`)."""
        if status > 1:
            label = _STATUS[status] if 0 <= status < len(_STATUS) else str(status)
            raise FMIError(function, self.name, label, self.messages)

    # ------------------------------------------------------------------ hot path (addresses)
    def set_states_at(self, address: int) -> None:
        """fmi2SetContinuousStates from ``n_states`` doubles at ``address``."""
        self._check("fmi2SetContinuousStates",
                    self._hot["fmi2SetContinuousStates"](self._component, address, self.n_states))

    def get_states_at(self, address: int) -> None:
        """fmi2GetContinuousStates into ``n_states`` doubles at ``address``."""
        self._check("fmi2GetContinuousStates",
                    self._hot["fmi2GetContinuousStates"](self._component, address, self.n_states))

    def get_derivatives_at(self, address: int) -> None:
        """fmi2GetDerivatives into ``n_states`` doubles at ``address``."""
        self._check("fmi2GetDerivatives", self._hot["fmi2GetDerivatives"](self._component, address, self.n_states))

    def get_event_indicators_at(self, address: int) -> None:
        """fmi2GetEventIndicators into ``n_event_indicators`` doubles at ``address``."""
        self._check("fmi2GetEventIndicators",
                    self._hot["fmi2GetEventIndicators"](self._component, address, self.n_event_indicators))

    def link(self, outputs: list[str], target: "ModelExchangeInstance", inputs: list[str]):
        """A call that copies this instance's ``outputs`` to ``target``'s ``inputs`` (one buffer)."""
        source_vrs = np.array(self.value_references(outputs), dtype=np.uint32)
        target_vrs = np.array(target.value_references(inputs), dtype=np.uint32)
        buffer = np.zeros(len(outputs))
        n, get, put = len(outputs), self._hot["fmi2GetReal"], target._hot["fmi2SetReal"]
        source_address, target_address = source_vrs.ctypes.data, target_vrs.ctypes.data
        buffer_address = buffer.ctypes.data
        keep = (source_vrs, target_vrs, buffer)  # the arrays must outlive the closure's addresses

        def copy() -> None:
            self._check("fmi2GetReal", get(self._component, source_address, n, buffer_address))
            target._check("fmi2SetReal", put(target._component, target_address, n, buffer_address))
        copy.keep = keep
        return copy

    # ------------------------------------------------------------------ variables
    def value_references(self, names: Iterable[str]) -> list[int]:
        return [self.info.variable(name).value_reference for name in names]

    def set_parameters(self, values: Mapping[str, float]) -> None:
        """Set parameters by name (before initialization, or tunable ones in event mode)."""
        valid = self.info.parameters
        unknown = [name for name in values if name not in valid]
        if unknown:
            raise InputError(
                f"{self.info.path}: {self.info.model_name} has no parameter "
                f"{', '.join(map(repr, unknown))}; valid parameters: {', '.join(valid)}")
        self.set_real(self.value_references(values), [float(v) for v in values.values()])

    def set_real(self, value_references: Iterable[int], values: Iterable[float]) -> None:
        vrs, n = self._vrs(value_references)
        data = np.ascontiguousarray(np.fromiter(values, dtype=float, count=n))
        self._call("fmi2SetReal", vrs, n, self._pointer(data))

    def get_real(self, value_references: Iterable[int]) -> np.ndarray:
        vrs, n = self._vrs(value_references)
        out = np.zeros(n)
        self._call("fmi2GetReal", vrs, n, self._pointer(out))
        return out

    def reader(self, names: Iterable[str]):
        """A fast getter of the named variables: ``read() -> ndarray`` (no per-call lookup)."""
        vrs, n = self._vrs(self.value_references(names))
        out = np.zeros(n)
        pointer = self._pointer(out)

        def read() -> np.ndarray:
            self._call("fmi2GetReal", vrs, n, pointer)
            return out.copy()
        return read

    def writer(self, names: Iterable[str]):
        """A fast setter of the named variables: ``write(values)``."""
        vrs, n = self._vrs(self.value_references(names))
        data = np.zeros(n)
        pointer = self._pointer(data)

        def write(values) -> None:
            data[:] = values
            self._call("fmi2SetReal", vrs, n, pointer)
        return write

    # ------------------------------------------------------------------ life cycle
    def setup_experiment(self, start_time: float = 0.0, tolerance: float | None = None) -> None:
        self._call("fmi2SetupExperiment", tolerance is not None, tolerance or 0.0, start_time, False, 0.0)

    def enter_initialization_mode(self) -> None:
        self._call("fmi2EnterInitializationMode")

    def exit_initialization_mode(self) -> None:
        self._call("fmi2ExitInitializationMode")

    def enter_event_mode(self) -> None:
        self._call("fmi2EnterEventMode")

    def update_discrete_states(self, max_iterations: int = 100) -> EventResult:
        """Iterate fmi2NewDiscreteStates until the FMU needs no more (FMI 2.0 event iteration)."""
        from fmpy.fmi2 import fmi2EventInfo

        info = fmi2EventInfo()
        changed = False
        for _ in range(max_iterations):
            self._call("fmi2NewDiscreteStates", ctypes.byref(info))
            changed |= bool(info.valuesOfContinuousStatesChanged)
            if info.terminateSimulation or not info.newDiscreteStatesNeeded:
                break
        else:
            raise FMIError("fmi2NewDiscreteStates", self.name,
                           f"no fixed point after {max_iterations} event iterations")
        return EventResult(terminate=bool(info.terminateSimulation), states_changed=changed,
                           next_event_time=info.nextEventTime if info.nextEventTimeDefined else None)

    def enter_continuous_time_mode(self) -> None:
        self._call("fmi2EnterContinuousTimeMode")

    def completed_integrator_step(self) -> tuple[bool, bool]:
        """Returns (enter event mode, terminate simulation)."""
        from fmpy.fmi2 import fmi2Boolean

        enter, terminate = fmi2Boolean(), fmi2Boolean()
        self._call("fmi2CompletedIntegratorStep", True, ctypes.byref(enter), ctypes.byref(terminate))
        return bool(enter.value), bool(terminate.value)

    def set_time(self, time: float) -> None:
        self._check("fmi2SetTime", self._hot["fmi2SetTime"](self._component, time))

    def get_states(self, out: np.ndarray | None = None) -> np.ndarray:
        """Continuous states, into ``out`` if given (else a new array)."""
        if self.n_states:
            self._call("fmi2GetContinuousStates", self._x_ptr, self.n_states)
        if out is None:
            return self._x.copy()
        out[:] = self._x
        return out

    def set_states(self, x: np.ndarray) -> None:
        if self.n_states:
            self._x[:] = x
            self._call("fmi2SetContinuousStates", self._x_ptr, self.n_states)

    def get_derivatives(self, out: np.ndarray | None = None) -> np.ndarray:
        """State derivatives, into ``out`` if given (else a new array)."""
        if self.n_states:
            self._call("fmi2GetDerivatives", self._dx_ptr, self.n_states)
        if out is None:
            return self._dx.copy()
        out[:] = self._dx
        return out

    def get_nominals(self) -> np.ndarray:
        out = np.ones(self.n_states)
        if self.n_states:
            self._call("fmi2GetNominalsOfContinuousStates", self._pointer(out), self.n_states)
        return out

    def terminate(self) -> None:
        self._call("fmi2Terminate")

    def reset(self) -> None:
        self._call("fmi2Reset")

    def free(self) -> None:
        """Free the instance and unload the binary (safe to call twice)."""
        if self._model is not None:
            model, self._model = self._model, None
            model.fmi2FreeInstance(self._component)
            model.freeLibrary()

    def __enter__(self) -> "ModelExchangeInstance":
        return self

    def __exit__(self, *exc) -> None:
        self.free()
