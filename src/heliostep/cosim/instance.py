"""What every Model Exchange instance shares, whatever its FMI version: the life cycle and the one error path.

:class:`ModelExchangeBase` loads the binary (fmpy), instantiates, binds the FMI functions and calls
each of them through :meth:`~ModelExchangeBase._call`, which raises :class:`FMIError` for a status worse
than warning; :mod:`~heliostep.cosim.fmi` (FMI 2.0) and :mod:`~heliostep.cosim.fmi3` (FMI 3.0) give what
their version does differently. Every instance is reached through the same fmi2-shaped calls
(``fmi2GetReal`` ...), so the master and the compiled kernel treat both alike. Each instance's log
messages are routed to it by its ``componentEnvironment`` (fmpy's logger proxy keeps one logger per process).
"""

from __future__ import annotations

import ctypes
import itertools
import logging as _logging
import weakref
from collections import deque
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from heliostep.cosim import watch
from heliostep.cosim.access import VariableAccess
from heliostep.cosim.description import FMUInfo, _extract
from heliostep.cosim.kinds import LifeCycle
from heliostep.errors import RunFailure

__all__ = ["FMIError", "EventResult", "ModelExchangeBase", "address"]


class FMIError(RunFailure):
    """An FMI function returned an error or fatal status (or an FMU could not be loaded): a run failure."""

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

#: componentEnvironment (an int id) -> instance; the one logger callback looks the instance up
_by_environment: weakref.WeakValueDictionary[int, Any] = weakref.WeakValueDictionary()
_environment_ids = itertools.count(1)


def _dispatch_log(environment, instance_name, status, category, message) -> None:
    """The logger of every instance of every version: the message goes to the instance whose
    componentEnvironment the FMU passes back (by instance name for FMUs that pass none)."""
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


#: Prototypes of the fmi2-shaped calls, taking plain addresses (ints) for arrays: converting an int is
#: much cheaper for ctypes than a typed pointer.
ARRAY_CALL = ctypes.CFUNCTYPE(ctypes.c_int, ctypes.c_void_p, ctypes.c_void_p, ctypes.c_size_t)
VALUES_CALL = ctypes.CFUNCTYPE(ctypes.c_int, ctypes.c_void_p, ctypes.c_void_p, ctypes.c_size_t, ctypes.c_void_p)
STATUS_ONLY = ctypes.CFUNCTYPE(ctypes.c_int, ctypes.c_void_p)
_TIME_CALL = ctypes.CFUNCTYPE(ctypes.c_int, ctypes.c_void_p, ctypes.c_double)
#: the calls on the integrator's hot path, taking the component as their first argument
HOT_CALLS = {
    "fmi2SetTime": _TIME_CALL,
    "fmi2SetContinuousStates": ARRAY_CALL,
    "fmi2GetContinuousStates": ARRAY_CALL,
    "fmi2GetDerivatives": ARRAY_CALL,
    "fmi2GetEventIndicators": ARRAY_CALL,
    "fmi2GetReal": VALUES_CALL,
    "fmi2SetReal": VALUES_CALL,
}
#: every fmi2-shaped call an instance of any version has
SHAPED_CALLS = {
    **HOT_CALLS,
    **{name: VALUES_CALL for name in ("fmi2GetInteger", "fmi2SetInteger", "fmi2GetBoolean", "fmi2SetBoolean")},
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


class ModelExchangeBase(VariableAccess):
    """One instance of a Model Exchange FMU; a subclass per FMI version.

    Parameters
    ----------
    info : FMUInfo
        The FMU, from :func:`~heliostep.cosim.description.read_fmu`.
    instance_name : str
        Name used in log messages and errors.
    parameters : mapping of str to value, optional
        Parameter values set right after instantiation (each with the set function of its
        type); an unknown name raises :class:`InputError` listing the valid names.
    logging : bool, optional
        The FMU's own debug logging.
    index : int, optional
        The instance's position in the master's order, noted before each FMI call for a
        supervisor (:mod:`heliostep.cosim.watch`).

    ``mode`` follows FMI's state machine as seen from the master ("instantiated",
    "initialization", "event", "continuous", "terminated", "error", "fatal", "freed"), so that
    :meth:`close` terminates only where the standard allows it.
    """

    #: the version's life-cycle functions
    _life: LifeCycle
    #: the version's ctypes Boolean
    _BOOLEAN: Any = ctypes.c_bool
    #: the FMU's own instance (fmi2Component, fmi3Instance) and what the fmi2-shaped calls take
    _handle: Any = None
    _component: Any = None

    def __init__(
        self,
        info: FMUInfo,
        instance_name: str,
        parameters: Mapping[str, object] | None = None,
        logging: bool = False,
        index: int = -1,
    ):
        self.info, self.name, self.index = info, instance_name, index
        self.messages: deque[str] = deque(maxlen=50)
        self.n_states, self.n_event_indicators = len(info.states), info.n_event_indicators
        self.time, self.mode = float("nan"), "freed"
        self._model: Any = None
        self._tolerance: float | None = None
        self._environment = next(_environment_ids)
        _by_environment[self._environment] = self
        self._functions: dict[str, Callable[..., int]] = {}
        try:
            watch.note(index, "loading the binary", self.time)
            self._model = self._fmpy_model()(
                guid=info.guid,
                unzipDirectory=_extract(info.path),
                modelIdentifier=info.model_identifier,
                instanceName=instance_name,
            )
            watch.note(index, self._life.instantiate, self.time)
            self._instantiate(logging)
        except Exception as exc:
            if self._model is not None:
                try:
                    self._model.freeLibrary()
                except Exception:  # noqa: BLE001
                    pass
            self._model = None
            raise FMIError(self._life.instantiate, instance_name, f"failure ({exc})", self.messages) from None
        self.mode = "instantiated"
        self._bind()
        # buffers with cached pointers for the calls on the integrator's hot path
        self._x, self._dx = np.zeros(self.n_states), np.zeros(self.n_states)
        self._x_ptr, self._dx_ptr = self._pointer(self._x), self._pointer(self._dx)
        if parameters:
            try:
                self.set_parameters(parameters)
            except BaseException:  # the instance must not outlive a failed construction
                self.free()
                raise

    # ------------------------------------------------------------------ what a version gives
    def _fmpy_model(self) -> Any:
        """fmpy's class loading the version's binary."""
        raise NotImplementedError

    def _instantiate(self, logging: bool) -> None:
        """Instantiate: set ``_handle`` (the FMU's own instance) and ``_component`` (what the fmi2-shaped
        calls take)."""
        raise NotImplementedError

    def _bind(self) -> None:
        """``_functions`` (each bound to its first argument) and ``_hot`` (taking the component)."""
        raise NotImplementedError

    def _address(self, name: str) -> int:
        """The address of the fmi2-shaped function ``name`` taking :attr:`component`."""
        raise NotImplementedError

    def _update_once(self, iteration: int, first: Any) -> tuple[bool, bool, bool, bool, float | None]:
        """Call ``iteration`` of the event iteration: (more needed, terminate, states changed, nominals changed,
        next event time or None)."""
        raise NotImplementedError

    # ------------------------------------------------------------------ for C code calling the FMU
    @property
    def component(self) -> int:
        """The handle the fmi2-shaped calls take (an address; 0 once freed), for C code calling the FMU."""
        return int(self._component or 0)

    def function_address(self, name: str) -> int:
        """The address of the fmi2-shaped function ``name`` (e.g. ``"fmi2GetReal"``) taking :attr:`component`."""
        if self._model is None:
            raise FMIError(name, self.name, "no instance (freed, library unloaded)", (), self.time)
        return self._address(name)

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

    def _call(self, function: str, *args: Any) -> int:
        """Call the FMI function ``function`` (bound to its instance); raise :class:`FMIError` on error or fatal."""
        if self._model is None:
            raise FMIError(function, self.name, "no instance (freed, library unloaded)", (), self.time)
        if self.messages:
            self.messages.clear()
        watch.note(self.index, function, self.time)
        status = self._functions[function](*args)
        if status > 1:  # worse than a warning
            raise self.status_error(function, status)
        return status

    def _check(self, function: str, status: int) -> None:
        """The error path of the hot calls (as :meth:`_call`'s)."""
        if status > 1:
            raise self.status_error(function, status)

    def _freed(self, function: str) -> Callable[..., int]:
        def call(*args):
            raise FMIError(function, self.name, "no instance (freed, library unloaded)", (), self.time)

        return call

    def set_time(self, time: float) -> None:
        self.time = time
        watch.note(self.index, "fmi2SetTime", self.time)
        self._check("fmi2SetTime", self._hot["fmi2SetTime"](self._component, time))

    def get_states(self, out: np.ndarray | None = None) -> np.ndarray:
        """Continuous states, into ``out`` if given (else a new array)."""
        return self._vector("fmi2GetContinuousStates", self._x, self._x_ptr, out)

    def set_states(self, x: np.ndarray) -> None:
        if self.n_states:
            self._x[:] = x
            self._call("fmi2SetContinuousStates", self._x_ptr, self.n_states)

    def get_derivatives(self, out: np.ndarray | None = None) -> np.ndarray:
        """State derivatives, into ``out`` if given (else a new array)."""
        return self._vector("fmi2GetDerivatives", self._dx, self._dx_ptr, out)

    def _vector(self, function: str, buffer: np.ndarray, pointer: Any, out: np.ndarray | None) -> np.ndarray:
        if self.n_states:
            self._call(function, pointer, self.n_states)
        if out is None:
            return buffer.copy()
        out[:] = buffer
        return out

    # ------------------------------------------------------------------ life cycle
    def _into(self, function: str, mode: str, *args: Any) -> None:
        """Call the life-cycle function ``function``, which puts the instance into ``mode``."""
        self._call(function, *args)
        self.mode = mode

    def setup_experiment(self, start_time: float = 0.0, tolerance: float | None = None) -> None:
        """The start time [s] and tolerance of the experiment, before initialization mode."""
        self.time, self._tolerance = start_time, tolerance

    def enter_initialization_mode(self) -> None:
        self._into(self._life.enter_initialization_mode, "initialization")

    def exit_initialization_mode(self) -> None:
        self._into(self._life.exit_initialization_mode, "event")

    def enter_event_mode(self) -> None:
        self._into(self._life.enter_event_mode, "event")

    def update_discrete_states(self, max_iterations: int = 100, first: Any = None) -> EventResult:
        """Iterate the event update until the FMU needs no more (or asks to terminate); ``first``: the
        answer of a first call already made (FMI 2.0's, by the compiled kernel, :mod:`~heliostep.cosim.fast_events`)."""
        changed = nominals = False
        for iteration in range(max_iterations):
            more, terminate, values, nominal, next_time = self._update_once(iteration, first)
            changed |= values
            nominals |= nominal
            if terminate or not more:
                break
        else:
            raise FMIError(
                self._life.update_discrete_states,
                self.name,
                f"no fixed point after {max_iterations} event iterations",
                self.messages,
                self.time,
            )
        return EventResult(
            terminate=terminate, states_changed=changed, next_event_time=next_time, nominals_changed=nominals
        )

    def enter_continuous_time_mode(self) -> None:
        self._into(self._life.enter_continuous_time_mode, "continuous")

    def completed_integrator_step(self) -> tuple[bool, bool]:
        """Returns (enter event mode, terminate simulation)."""
        enter, terminate = self._BOOLEAN(), self._BOOLEAN()
        self._call(self._life.completed_integrator_step, True, ctypes.byref(enter), ctypes.byref(terminate))
        return bool(enter.value), bool(terminate.value)

    def get_nominals(self) -> np.ndarray:
        out = np.ones(self.n_states)
        if self.n_states:
            self._call(self._life.get_nominals, out.ctypes.data, self.n_states)
        return out

    def terminate(self) -> None:
        self._into(self._life.terminate, "terminated")

    def reset(self) -> None:
        self._into(self._life.reset, "instantiated")

    def close(self) -> None:
        """End the instance on any path: terminate where the state machine allows it (event,
        continuous-time or error mode), then free the instance and unload (never raises)."""
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

        After a fatal status no function may be called on the FMU any more, not even its
        FreeInstance: the library is only unloaded. Every later call raises :class:`FMIError`.
        """
        if self._model is not None:
            model, self._model = self._model, None
            self._hot = {name: self._freed(name) for name in HOT_CALLS}
            try:
                if self.mode != "fatal":
                    watch.note(self.index, self._life.free_instance, self.time)
                    getattr(model, self._life.free_instance)(self._handle)
            finally:
                self.mode = "freed"
                self._component = None
                model.freeLibrary()

    def __enter__(self) -> ModelExchangeBase:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
