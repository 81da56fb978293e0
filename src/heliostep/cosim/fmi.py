"""FMU instances: fmpy's FMI 2.0 Model Exchange loading behind a small API, and the one error path.

The FMI API of heliostep lives here: reading and checking ``modelDescription.xml``
(:func:`read_fmu`, re-exported from :mod:`~heliostep.cosim.description`), loading the binary
(``fmpy.fmi2.FMU2Model``) and the calls on an instance (:class:`ModelExchangeInstance`: its life
cycle and the calls on the integrator's hot path here, the typed access to its variables in
:class:`~heliostep.cosim.access.VariableAccess`). The FMI functions are bound here with their own
prototypes, from the loaded library. There is one error path: any FMI call that returns a status
worse than warning raises :class:`FMIError`, which names the function, the instance, the
simulation time and the messages the FMU logged (:meth:`ModelExchangeInstance.status_error`
turns a status into it, also for the compiled kernel, which gets the instance's handle and
function addresses from :attr:`ModelExchangeInstance.component` and
:meth:`ModelExchangeInstance.function_address`). Outside :mod:`heliostep.cosim`, nothing of
heliostep touches ctypes.

Each instance gets its own logger callback identified by FMI's ``componentEnvironment``, so an
FMU's messages always stay with its instance (fmpy's logger proxy keeps one logger per process).
"""

from __future__ import annotations

import ctypes
import itertools
import logging as _logging
import weakref
from collections import deque
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass

import numpy as np

from heliostep.cosim import watch
from heliostep.cosim.access import VariableAccess
from heliostep.cosim.description import (  # noqa: F401 - re-exported: the FMI API lives here
    REQUIRED_FUNCTIONS,
    FMUInfo,
    VariableInfo,
    _extract,
    convert_value,
    read_fmu,
)
from heliostep.errors import RunFailure


class FMIError(RunFailure):
    """An FMI function returned fmi2Error or fmi2Fatal (or an FMU could not be loaded): a run failure."""

    def __init__(
        self, function: str, instance: str, status: str, messages: Iterable[str] = (), time: float | None = None
    ):
        self.function = function
        self.instance = instance
        self.status = status
        self.messages = list(messages)[-5:]  # the FMU's own last messages
        self.time = time
        at = f" at t = {time:.9g} s" if time is not None and np.isfinite(time) else ""
        detail = f": {' | '.join(self.messages)}" if self.messages else ""
        super().__init__(f"{instance}: {function} returned {status}{at}{detail}")


_STATUS = ["fmi2OK", "fmi2Warning", "fmi2Discard", "fmi2Error", "fmi2Fatal", "fmi2Pending"]

_log = _logging.getLogger("heliostep.fmu")
_log.addHandler(_logging.NullHandler())  # the application decides where FMU messages go

# ---------------------------------------------------------------------- per-instance logging
#: componentEnvironment (an int id) -> instance; the one logger callback looks the instance up
_by_environment: weakref.WeakValueDictionary[int, ModelExchangeInstance] = weakref.WeakValueDictionary()
_environment_ids = itertools.count(1)
_logger_callback = None


def _dispatch_log(environment, instance_name, status, category, message) -> None:
    """The fmi2CallbackLogger of every instance: the message goes to the instance whose
    componentEnvironment the FMU passes back (by instance name for FMUs that pass none). fmpy's native
    logger proxy (which formats the printf-style arguments ctypes cannot see) keeps a single logger per
    process; it is always this one function, so that does not matter."""
    try:
        instance = _by_environment.get(environment or 0)
        name = instance_name.decode("utf-8", "replace") if isinstance(instance_name, bytes) else str(instance_name)
        if instance is None:
            instance = next((i for i in list(_by_environment.values()) if i.name == name), None)
        text = message.decode("utf-8", "replace") if isinstance(message, bytes) else str(message)
        label = _STATUS[status] if 0 <= status < len(_STATUS) else str(status)
        if instance is not None:
            instance.messages.append(text)
        _log.log(
            _logging.WARNING if status >= 1 else _logging.DEBUG,
            "%s [%s] %s",
            instance.name if instance is not None else name,
            label,
            text,
        )
    except Exception:  # noqa: BLE001 - a logger must never raise into the FMU
        pass


def _logger():
    global _logger_callback
    if _logger_callback is None:
        from fmpy.fmi2 import fmi2CallbackLoggerTYPE

        _logger_callback = fmi2CallbackLoggerTYPE(_dispatch_log)
    return _logger_callback


#: Prototypes of the calls on the integrator's hot path, taking plain addresses (ints) for
#: arrays: converting an int is much cheaper for ctypes than a typed pointer.
_ARRAY_CALL = ctypes.CFUNCTYPE(ctypes.c_int, ctypes.c_void_p, ctypes.c_void_p, ctypes.c_size_t)
_VALUES_CALL = ctypes.CFUNCTYPE(ctypes.c_int, ctypes.c_void_p, ctypes.c_void_p, ctypes.c_size_t, ctypes.c_void_p)
_TIME_CALL = ctypes.CFUNCTYPE(ctypes.c_int, ctypes.c_void_p, ctypes.c_double)
_HOT_CALLS = {
    "fmi2SetTime": _TIME_CALL,
    "fmi2SetContinuousStates": _ARRAY_CALL,
    "fmi2GetContinuousStates": _ARRAY_CALL,
    "fmi2GetDerivatives": _ARRAY_CALL,
    "fmi2GetEventIndicators": _ARRAY_CALL,
    "fmi2GetReal": _VALUES_CALL,
    "fmi2SetReal": _VALUES_CALL,
}

#: Prototypes of every FMI function :meth:`ModelExchangeInstance._call` calls (pointers as void *).
_STATUS_ONLY = ctypes.CFUNCTYPE(ctypes.c_int, ctypes.c_void_p)
_CALLS = {
    **{
        name: _VALUES_CALL
        for name in (
            "fmi2GetReal",
            "fmi2SetReal",
            "fmi2GetInteger",
            "fmi2SetInteger",
            "fmi2GetBoolean",
            "fmi2SetBoolean",
            "fmi2GetString",
            "fmi2SetString",
        )
    },
    **{
        name: _ARRAY_CALL
        for name in (
            "fmi2GetContinuousStates",
            "fmi2SetContinuousStates",
            "fmi2GetDerivatives",
            "fmi2GetNominalsOfContinuousStates",
        )
    },
    **{
        name: _STATUS_ONLY
        for name in (
            "fmi2EnterInitializationMode",
            "fmi2ExitInitializationMode",
            "fmi2EnterEventMode",
            "fmi2EnterContinuousTimeMode",
            "fmi2Terminate",
            "fmi2Reset",
        )
    },
    "fmi2SetupExperiment": ctypes.CFUNCTYPE(
        ctypes.c_int, ctypes.c_void_p, ctypes.c_int, ctypes.c_double, ctypes.c_double, ctypes.c_int, ctypes.c_double
    ),
    "fmi2NewDiscreteStates": ctypes.CFUNCTYPE(ctypes.c_int, ctypes.c_void_p, ctypes.c_void_p),
    "fmi2CompletedIntegratorStep": ctypes.CFUNCTYPE(
        ctypes.c_int, ctypes.c_void_p, ctypes.c_int, ctypes.c_void_p, ctypes.c_void_p
    ),
}


def address(pointer) -> int:
    """The address of a ctypes pointer (e.g. the data of a SUNDIALS vector) as an int."""
    return ctypes.cast(pointer, ctypes.c_void_p).value or 0


@dataclass(frozen=True)
class EventResult:
    """What an event iteration told the master."""

    terminate: bool = False
    states_changed: bool = False
    next_event_time: float | None = None
    nominals_changed: bool = False  # nominalsOfContinuousStatesChanged: read them again


def _callbacks(environment: int):
    """fmi2CallbackFunctions for one instance: heliostep's logger (routed by componentEnvironment), fmpy's memory."""
    from fmpy import calloc, free
    from fmpy.fmi2 import fmi2CallbackAllocateMemoryTYPE, fmi2CallbackFreeMemoryTYPE, fmi2CallbackFunctions

    callbacks = fmi2CallbackFunctions()
    callbacks.logger = _logger()
    callbacks.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
    callbacks.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
    callbacks.componentEnvironment = environment
    try:  # fmpy's native proxy formats the printf-style arguments, then calls _dispatch_log
        from fmpy.logging import addLoggerProxy

        addLoggerProxy(ctypes.byref(callbacks))
    except Exception:  # noqa: BLE001 - without it messages stay unformatted
        pass
    return callbacks


class ModelExchangeInstance(VariableAccess):
    """One instance of an FMI 2.0 Model Exchange FMU.

    Parameters
    ----------
    info : FMUInfo
        The FMU, from :func:`read_fmu`.
    instance_name : str
        Name used in log messages and errors.
    parameters : mapping of str to value, optional
        Parameter values set right after instantiation (each with the set function of its
        type); an unknown name raises :class:`InputError` listing the valid names.
    index : int, optional
        The instance's position in the master's order, noted before each FMI call for a
        supervisor (:mod:`heliostep.cosim.watch`; nothing is noted when no record is attached).

    The typed access to variables (``set_real``, ``reader``, ``writer``, ``link``,
    ``set_parameters`` ...) is inherited from :class:`~heliostep.cosim.access.VariableAccess`.
    ``mode`` follows FMI's state machine as seen from the master ("instantiated",
    "initialization", "event", "continuous", "terminated", "error", "fatal", "freed"), so that
    :meth:`close` calls ``fmi2Terminate`` only where the standard allows it.
    """

    def __init__(
        self,
        info: FMUInfo,
        instance_name: str,
        parameters: Mapping[str, object] | None = None,
        logging: bool = False,
        index: int = -1,
    ):
        from fmpy.fmi2 import FMU2Model

        self.info = info
        self.name = instance_name
        self.index = index
        self.messages: deque[str] = deque(maxlen=50)
        self.n_states = len(info.states)
        self.n_event_indicators = info.n_event_indicators
        self.time = float("nan")
        self.mode = "freed"
        self._model = None
        self._environment = next(_environment_ids)
        _by_environment[self._environment] = self
        self._callbacks = _callbacks(self._environment)
        try:
            unpacked = _extract(info.path)
            watch.note(index, "loading the binary", self.time)
            self._model = FMU2Model(
                guid=info.guid,
                unzipDirectory=unpacked,
                modelIdentifier=info.model_identifier,
                instanceName=instance_name,
            )
            watch.note(index, "fmi2Instantiate", self.time)
            self._model.instantiate(callbacks=self._callbacks, loggingOn=logging)
        except Exception as exc:
            if self._model is not None:
                try:
                    self._model.freeLibrary()
                except Exception:  # noqa: BLE001
                    pass
            self._model = None
            raise FMIError("fmi2Instantiate", instance_name, f"failure ({exc})", self.messages) from None
        self.mode = "instantiated"
        self._component = self._model.component
        dll = self._model.dll
        self._functions = {name: prototype((name, dll)) for name, prototype in _CALLS.items()}
        self._hot = {name: prototype((name, self._model.dll)) for name, prototype in _HOT_CALLS.items()}
        # buffers with cached pointers for the calls on the integrator's hot path
        self._x, self._dx = np.zeros(self.n_states), np.zeros(self.n_states)
        self._x_ptr, self._dx_ptr = self._pointer(self._x), self._pointer(self._dx)
        if parameters:
            try:
                self.set_parameters(parameters)
            except BaseException:  # the instance must not outlive a failed construction
                self.free()
                raise

    # ------------------------------------------------------------------ for C code calling the FMU
    @property
    def component(self) -> int:
        """The ``fmi2Component`` handle (an address; 0 once freed), for C code calling the FMU itself."""
        return int(self._component or 0)

    def function_address(self, name: str) -> int:
        """The address of the FMU's FMI function ``name`` (e.g. ``"fmi2GetReal"``) in its loaded library."""
        if self._model is None:
            raise FMIError(name, self.name, "no instance (freed, library unloaded)", (), self.time)
        return ctypes.cast(self._model.dll[name], ctypes.c_void_p).value or 0

    # ------------------------------------------------------------------ the error path
    def status_error(self, function: str, status: int | str) -> FMIError:
        """The :class:`FMIError` of ``function`` returning ``status`` (a status or a text), with the FMU's messages
        since the last call and the instance's time; an error or fatal status sets that mode. Messages go once."""
        if isinstance(status, int):
            if status == 3:
                self.mode = "error"
            elif status >= 4:
                self.mode = "fatal"
            names = [n.replace("fmi2", function[:4]) for n in _STATUS]  # the function's own version's names
            status = names[status] if 0 <= status < len(names) else str(status)
        error = FMIError(function, self.name, status, self.messages, self.time)
        self.messages.clear()  # never reported twice, never with a later error
        return error

    def _call(self, function: str, *args):
        """Call the FMI function ``function``; raise :class:`FMIError` on error or fatal.

        The function is called through heliostep's own prototype on the loaded library
        (fmpy's per-call wrapper costs more than the model evaluation itself).
        """
        if self._model is None:
            raise FMIError(function, self.name, "no instance (freed, library unloaded)", (), self.time)
        if self.messages:
            self.messages.clear()
        watch.note(self.index, function, self.time)
        status = self._functions[function](self._component, *args)
        if status > 1:  # worse than fmi2Warning
            raise self.status_error(function, status)
        return status

    def _check(self, function: str, status: int) -> None:
        """The error path of the hot calls (same as :meth:`_call`)."""
        if status > 1:
            raise self.status_error(function, status)

    def _freed(self, function: str) -> Callable[..., int]:
        def call(*args):
            raise FMIError(function, self.name, "no instance (freed, library unloaded)", (), self.time)

        return call

    # ------------------------------------------------------------------ hot path (addresses)
    def set_states_at(self, address: int) -> None:
        """fmi2SetContinuousStates from ``n_states`` doubles at ``address``."""
        watch.note(self.index, "fmi2SetContinuousStates", self.time)
        self._check(
            "fmi2SetContinuousStates", self._hot["fmi2SetContinuousStates"](self._component, address, self.n_states)
        )

    def get_states_at(self, address: int) -> None:
        """fmi2GetContinuousStates into ``n_states`` doubles at ``address``."""
        watch.note(self.index, "fmi2GetContinuousStates", self.time)
        self._check(
            "fmi2GetContinuousStates", self._hot["fmi2GetContinuousStates"](self._component, address, self.n_states)
        )

    def get_derivatives_at(self, address: int) -> None:
        """fmi2GetDerivatives into ``n_states`` doubles at ``address``."""
        watch.note(self.index, "fmi2GetDerivatives", self.time)
        self._check("fmi2GetDerivatives", self._hot["fmi2GetDerivatives"](self._component, address, self.n_states))

    def get_event_indicators_at(self, address: int) -> None:
        """fmi2GetEventIndicators into ``n_event_indicators`` doubles at ``address``."""
        watch.note(self.index, "fmi2GetEventIndicators", self.time)
        self._check(
            "fmi2GetEventIndicators",
            self._hot["fmi2GetEventIndicators"](self._component, address, self.n_event_indicators),
        )

    # ------------------------------------------------------------------ life cycle
    def setup_experiment(self, start_time: float = 0.0, tolerance: float | None = None) -> None:
        self.time = start_time
        self._call("fmi2SetupExperiment", tolerance is not None, tolerance or 0.0, start_time, False, 0.0)

    def enter_initialization_mode(self) -> None:
        self._call("fmi2EnterInitializationMode")
        self.mode = "initialization"

    def exit_initialization_mode(self) -> None:
        self._call("fmi2ExitInitializationMode")
        self.mode = "event"

    def enter_event_mode(self) -> None:
        self._call("fmi2EnterEventMode")
        self.mode = "event"

    def update_discrete_states(self, max_iterations: int = 100, first=None) -> EventResult:
        """Iterate fmi2NewDiscreteStates until the FMU needs no more (FMI 2.0 event iteration); ``first``: the
        fmi2EventInfo of a first call already made (the compiled kernel's, :mod:`~heliostep.cosim.fast_events`)."""
        from fmpy.fmi2 import fmi2EventInfo

        info = fmi2EventInfo()
        changed = nominals = False
        for iteration in range(max_iterations):
            if iteration or first is None:
                self._call("fmi2NewDiscreteStates", ctypes.byref(info))
            else:  # the kernel's call: its answer
                ctypes.memmove(ctypes.byref(info), ctypes.byref(first), ctypes.sizeof(info))
            changed |= bool(info.valuesOfContinuousStatesChanged)
            nominals |= bool(info.nominalsOfContinuousStatesChanged)
            if info.terminateSimulation or not info.newDiscreteStatesNeeded:
                break
        else:
            raise FMIError(
                "fmi2NewDiscreteStates",
                self.name,
                f"no fixed point after {max_iterations} event iterations",
                self.messages,
                self.time,
            )
        return EventResult(
            terminate=bool(info.terminateSimulation),
            states_changed=changed,
            next_event_time=info.nextEventTime if info.nextEventTimeDefined else None,
            nominals_changed=nominals,
        )

    def enter_continuous_time_mode(self) -> None:
        self._call("fmi2EnterContinuousTimeMode")
        self.mode = "continuous"

    def completed_integrator_step(self) -> tuple[bool, bool]:
        """Returns (enter event mode, terminate simulation)."""
        from fmpy.fmi2 import fmi2Boolean

        enter, terminate = fmi2Boolean(), fmi2Boolean()
        self._call("fmi2CompletedIntegratorStep", True, ctypes.byref(enter), ctypes.byref(terminate))
        return bool(enter.value), bool(terminate.value)

    def set_time(self, time: float) -> None:
        self.time = time
        watch.note(self.index, "fmi2SetTime", self.time)
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
        self.mode = "terminated"

    def reset(self) -> None:
        self._call("fmi2Reset")
        self.mode = "instantiated"

    def close(self) -> None:
        """End the instance on any path: fmi2Terminate where the state machine allows it
        (event, continuous-time or error mode), then fmi2FreeInstance and unload (never raises)."""
        if self._model is not None and self.mode in ("event", "continuous", "error"):
            try:
                self.terminate()
            except Exception:  # noqa: BLE001 - closing must not hide the original error
                pass
        try:
            self.free()
        except Exception:  # noqa: BLE001
            pass

    def free(self) -> None:
        """Free the instance and unload the binary (safe to call twice).

        After fmi2Fatal no function may be called on the FMU any more, not even
        fmi2FreeInstance: the library is only unloaded. Every later call raises :class:`FMIError`.
        """
        if self._model is not None:
            model, self._model = self._model, None
            self._hot = {name: self._freed(name) for name in _HOT_CALLS}
            try:
                if self.mode != "fatal":
                    watch.note(self.index, "fmi2FreeInstance", self.time)
                    model.fmi2FreeInstance(self._component)
            finally:
                self.mode = "freed"
                self._component = None
                model.freeLibrary()

    def __enter__(self) -> ModelExchangeInstance:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
