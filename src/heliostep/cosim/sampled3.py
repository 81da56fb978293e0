"""FMI 3.0 Co-Simulation instances for sampled components (:mod:`heliostep.cosim.sampled`).

:class:`CoSimulation3Instance` has the API of :class:`~heliostep.cosim.sampled.CoSimulationInstance`
(FMI 2.0), so a :class:`~heliostep.cosim.sampled.SampledComponent` steps an FMI 2.0 or 3.0
Co-Simulation FMU alike. The binary is loaded by fmpy (``fmpy.fmi3.FMU3Slave``); the instance is
made with ``fmi3InstantiateCoSimulation`` called directly, so that its ``instanceEnvironment``
routes its log messages to it (fmpy's own ``instantiate`` passes none), with ``eventModeUsed`` and
``earlyReturnAllowed`` false and no intermediate update: the FMU handles its events inside
``fmi3DoStep`` and completes every step (FMI 3.0 standard, section 4.2, basic Co-Simulation).

The life cycle is FMI 3.0's: ``fmi3EnterInitializationMode`` (start and stop time; FMI 3.0 has no
``SetupExperiment``), parameters (each with its own ``fmi3Set*`` function) and inputs set,
``fmi3ExitInitializationMode`` (into Step Mode), ``fmi3DoStep`` from each communication point to the
next, ``fmi3Terminate``, ``fmi3FreeInstance``. What ``fmi3DoStep`` reports back:

- ``terminateSimulation``: the step's outputs are taken, then the run ends at that communication point
  (:class:`~heliostep.cosim.events.Terminated`, said in stdout and ``summary.json`` like a Model
  Exchange FMU's termination);
- ``earlyReturn`` (the step ended at ``lastSuccessfulTime``, before the point) or ``eventHandlingNeeded``
  (the FMU asks for Event Mode): the FMU was instantiated with neither allowed, so the run fails
  (:class:`~heliostep.cosim.fmi.FMIError`, exit 1) naming the instance, the flag and the time;
  heliostep does not run FMI 3.0's Co-Simulation Event Mode or early return.
"""

from __future__ import annotations

import ctypes
import os
from collections import deque
from collections.abc import Callable, Mapping, Sequence
from typing import Any

from heliostep.cosim.description import FMUInfo, _extract, convert_value
from heliostep.cosim.fmi import FMIError, _by_environment, _environment_ids
from heliostep.cosim.fmi3 import _logger3
from heliostep.errors import InputError

__all__ = ["CoSimulation3Instance"]

#: FMI 3.0 type -> fmpy's setter (``FMU3Slave.set<Type>``)
_SETTERS = {"Enumeration": "setInt64", "Boolean": "setBoolean", "String": "setString"}


class CoSimulation3Instance:
    """One instance of an FMI 3.0 Co-Simulation FMU, every FMI error an
    :class:`~heliostep.cosim.fmi.FMIError` naming the instance, the function, the time and the FMU's messages."""

    def __init__(self, info: FMUInfo, name: str, parameters: Mapping[str, object]):
        from fmpy.fmi3 import FMU3Slave, fmi3IntermediateUpdateCallback, fmi3ValueReference

        self.info, self.name = info, name
        self.messages: deque[str] = deque(maxlen=50)
        self.time = float("nan")
        self._environment = next(_environment_ids)
        _by_environment[self._environment] = self  # type: ignore[assignment]  # the logger routes by this
        self._types = {v.name: v.type for v in info.description.modelVariables}  # type: ignore[attr-defined]
        self._slave: Any = None
        slave = FMU3Slave(
            guid=info.guid, unzipDirectory=_extract(info.path), modelIdentifier=info.model_identifier, instanceName=name
        )
        resources = (os.path.join(slave.unzipDirectory, "resources") + os.path.sep).encode()
        required = (fmi3ValueReference * 0)()
        self._no_update = fmi3IntermediateUpdateCallback()  # NULL: no intermediate update
        try:
            slave.component = self._do(
                "fmi3InstantiateCoSimulation",
                slave.fmi3InstantiateCoSimulation,
                name.encode(),
                info.guid.encode(),
                resources,
                False,  # visible
                False,  # loggingOn
                False,  # eventModeUsed: events are the FMU's business inside fmi3DoStep
                False,  # earlyReturnAllowed: every step ends at the communication point
                required,
                0,
                ctypes.c_void_p(self._environment),
                _logger3(),
                self._no_update,
            )
            if not slave.component:
                raise FMIError("fmi3InstantiateCoSimulation", name, "NULL", self.messages, self.time)
        except BaseException:
            slave.freeLibrary()
            raise
        self._slave = slave
        self._parameters = dict(parameters)

    def _do(self, function: str, call: Callable[..., Any], *args: Any) -> Any:
        self.messages.clear()
        try:
            return call(*args)
        except Exception as exc:  # fmpy's FMICallException and the like
            raise FMIError(function, self.name, f"failure ({exc})", self.messages, self.time) from None

    def initialize(self, start_time: float, stop_time: float, inputs: Mapping[str, float]) -> None:
        """EnterInitializationMode (start and stop time), parameters and inputs set, ExitInitializationMode."""
        slave, variables = self._slave, self.info.variables
        self.time = start_time
        self._do("fmi3EnterInitializationMode", slave.enterInitializationMode, None, start_time, stop_time)
        for name, value in self._parameters.items():
            if name not in variables or variables[name].causality != "parameter":
                known = ", ".join(v for v in variables if variables[v].causality == "parameter")
                raise InputError(
                    f"{self.name} ({self.info.path.name}) has no parameter {name!r}; its parameters: {known}"
                )
            self._set(name, convert_value(variables[name], value))
        for name, value in inputs.items():
            self._set(name, value)
        self._do("fmi3ExitInitializationMode", slave.exitInitializationMode)

    def _set(self, name: str, value: Any) -> None:
        type_ = self._types[name]
        method = _SETTERS.get(type_, f"set{type_}")
        self._do(
            f"fmi3S{method[1:]}", getattr(self._slave, method), [self.info.variables[name].value_reference], [value]
        )

    def set_real(self, names: Sequence[str], values: Sequence[float]) -> None:
        refs = [self.info.variables[n].value_reference for n in names]
        self._do("fmi3SetFloat64", self._slave.setFloat64, refs, [float(v) for v in values])

    def get_real(self, names: Sequence[str]) -> list[float]:
        refs = [self.info.variables[n].value_reference for n in names]
        return list(self._do("fmi3GetFloat64", self._slave.getFloat64, refs))

    def do_step(self, to_time: float) -> bool:
        """fmi3DoStep from the instance's time to ``to_time`` [s]; whether the FMU asks to terminate
        the simulation (its outputs at ``to_time`` valid). An early return or a request for Event Mode
        is an :class:`FMIError` (neither was allowed at instantiation)."""
        flags = [ctypes.c_bool() for _ in range(3)]  # eventHandlingNeeded, terminateSimulation, earlyReturn
        last = ctypes.c_double()
        slave = self._slave
        self._do(
            "fmi3DoStep",
            slave.fmi3DoStep,
            slave.component,
            self.time,
            to_time - self.time,
            True,  # noSetFMUStatePriorToCurrentPoint
            *(ctypes.byref(flag) for flag in flags),
            ctypes.byref(last),
        )
        event, terminate, early = (flag.value for flag in flags)
        if early:
            raise FMIError(
                "fmi3DoStep",
                self.name,
                f"earlyReturn at lastSuccessfulTime = {last.value:.9g} s, before the communication point "
                f"{to_time:.9g} s, though instantiated with earlyReturnAllowed = false",
                self.messages,
                self.time,
            )
        self.time = to_time
        if event:
            raise FMIError(
                "fmi3DoStep",
                self.name,
                "eventHandlingNeeded, though instantiated with eventModeUsed = false (heliostep does not run FMI 3.0 "
                "Co-Simulation's Event Mode: the FMU must handle its events inside fmi3DoStep)",
                self.messages,
                self.time,
            )
        return bool(terminate)

    def close(self) -> None:
        """fmi3Terminate (errors ignored: the run's own error, if any, is what counts) and fmi3FreeInstance."""
        slave, self._slave = self._slave, None
        if slave is None:
            return
        for call in (slave.terminate, slave.freeInstance):
            try:
                call()
            except Exception:  # noqa: BLE001 - closing after a failure must not hide it
                pass
        try:
            slave.freeLibrary()
        except Exception:  # noqa: BLE001
            pass
