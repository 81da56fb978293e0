"""FMI 2.0 Model Exchange instances (fmpy's ``FMU2Model`` loads the binary), and the FMI API's names.

:class:`ModelExchangeInstance` gives what FMI 2.0 does its own way (instantiation with callback
functions, ``fmi2SetupExperiment``, the ``fmi2NewDiscreteStates`` iteration); the life cycle, the
error path and the variable access are its base's (:mod:`~heliostep.cosim.instance`). The FMI
functions are bound with heliostep's own prototypes (fmpy's per-call wrapper costs more than the
model evaluation itself).
"""

from __future__ import annotations

import ctypes
import functools
from typing import Any

from heliostep.cosim.description import (  # noqa: F401 - re-exported: the FMI API lives here
    FMUInfo,
    VariableInfo,
    convert_value,
    read_fmu,
)
from heliostep.cosim.instance import (  # noqa: F401 - re-exported
    ARRAY_CALL,
    HOT_CALLS,
    SHAPED_CALLS,
    STATUS_ONLY,
    VALUES_CALL,
    EventResult,
    FMIError,
    ModelExchangeBase,
    _dispatch_log,
    address,
)
from heliostep.cosim.kinds import life_cycle

_logger_callback = None


def _logger():
    """The one fmi2CallbackLogger of the process (fmpy's native proxy formats the printf-style arguments)."""
    global _logger_callback
    if _logger_callback is None:
        from fmpy.fmi2 import fmi2CallbackLoggerTYPE

        _logger_callback = fmi2CallbackLoggerTYPE(_dispatch_log)
    return _logger_callback


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


#: Prototypes of every FMI 2.0 function :meth:`ModelExchangeInstance._call` calls (pointers as void *).
_CALLS = {
    **SHAPED_CALLS,
    "fmi2GetString": VALUES_CALL,
    "fmi2SetString": VALUES_CALL,
    "fmi2GetNominalsOfContinuousStates": ARRAY_CALL,
    **{
        name: STATUS_ONLY
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


class ModelExchangeInstance(ModelExchangeBase):
    """One instance of an FMI 2.0 Model Exchange FMU (see :class:`~heliostep.cosim.instance.ModelExchangeBase`)."""

    _life = life_cycle("2.0")
    _BOOLEAN = ctypes.c_int  # fmi2Boolean

    def _fmpy_model(self) -> Any:
        from fmpy.fmi2 import FMU2Model

        return FMU2Model

    def _instantiate(self, logging: bool) -> None:
        self._callbacks = _callbacks(self._environment)
        self._model.instantiate(callbacks=self._callbacks, loggingOn=logging)
        self._handle = self._component = self._model.component

    def _bind(self) -> None:
        dll = self._model.dll
        self._functions = {
            name: functools.partial(prototype((name, dll)), self._component) for name, prototype in _CALLS.items()
        }
        self._hot = {name: prototype((name, dll)) for name, prototype in HOT_CALLS.items()}

    def _address(self, name: str) -> int:
        return ctypes.cast(self._model.dll[name], ctypes.c_void_p).value or 0

    def setup_experiment(self, start_time: float = 0.0, tolerance: float | None = None) -> None:
        super().setup_experiment(start_time, tolerance)
        self._call("fmi2SetupExperiment", tolerance is not None, tolerance or 0.0, start_time, False, 0.0)

    def _update_once(self, iteration: int, first: Any) -> tuple[bool, bool, bool, bool, float | None]:
        """One fmi2NewDiscreteStates (or ``first``, the fmi2EventInfo of a call the kernel made) into the
        iteration's fmi2EventInfo."""
        from fmpy.fmi2 import fmi2EventInfo

        if not iteration:
            self._event_info = fmi2EventInfo()
        info = self._event_info
        if iteration or first is None:
            self._call("fmi2NewDiscreteStates", ctypes.byref(info))
        else:
            ctypes.memmove(ctypes.byref(info), ctypes.byref(first), ctypes.sizeof(info))
        return (
            bool(info.newDiscreteStatesNeeded),
            bool(info.terminateSimulation),
            bool(info.valuesOfContinuousStatesChanged),
            bool(info.nominalsOfContinuousStatesChanged),
            info.nextEventTime if info.nextEventTimeDefined else None,
        )
