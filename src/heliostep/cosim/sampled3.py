"""FMI 3.0 Co-Simulation instances for sampled components (:mod:`heliostep.cosim.sampled`).

Instantiated with ``fmi3InstantiateCoSimulation`` called directly, so that its ``instanceEnvironment``
routes its log messages to it, with ``eventModeUsed`` and ``earlyReturnAllowed`` false (basic
Co-Simulation: the FMU handles its events inside ``fmi3DoStep``). A step's ``terminateSimulation`` ends
the run at that point; an ``earlyReturn`` or ``eventHandlingNeeded`` is an
:class:`~heliostep.cosim.instance.FMIError` (neither was allowed).
"""

from __future__ import annotations

import ctypes
import os
from collections.abc import Mapping

from heliostep.cosim.co_simulation import CoSimulationInstanceBase
from heliostep.cosim.description import FMUInfo
from heliostep.cosim.fmi3 import _logger3
from heliostep.cosim.instance import FMIError

__all__ = ["CoSimulation3Instance"]

#: FMI 3.0 type -> fmpy's setter (``FMU3Slave.set<Type>``)
_SETTERS = {"Enumeration": "setInt64", "Boolean": "setBoolean", "String": "setString"}


class CoSimulation3Instance(CoSimulationInstanceBase):
    """One instance of an FMI 3.0 Co-Simulation FMU, every FMI error an
    :class:`~heliostep.cosim.fmi.FMIError` naming the instance, the function, the time and the FMU's messages."""

    _FMI, _REAL = "fmi3", "Float64"
    TERMINATION = "fmi3DoStep: terminateSimulation"

    def __init__(self, info: FMUInfo, name: str, parameters: Mapping[str, object]):
        from fmpy.fmi3 import FMU3Slave, fmi3IntermediateUpdateCallback, fmi3ValueReference

        super().__init__(info, name, parameters)
        self._types = {v.name: v.type for v in info.description.modelVariables}  # type: ignore[attr-defined]
        slave = self._new_slave(FMU3Slave)
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

    def _enter_initialization_mode(self, start_time: float, stop_time: float) -> None:
        """fmi3EnterInitializationMode with the start and stop time [s] (FMI 3.0 has no SetupExperiment)."""
        self._do("fmi3EnterInitializationMode", self._slave.enterInitializationMode, None, start_time, stop_time)

    def _setter(self, name: str) -> str:
        type_ = self._types[name]
        return _SETTERS.get(type_, f"set{type_}")

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
