"""The kinds of FMU the master runs (FMI 2.0 and 3.0, Model Exchange and Co-Simulation): one entry each.

What differs between kinds is here and nowhere else; the rest of :mod:`heliostep.cosim` asks
:func:`kind_of`. Adding a kind is one module (its reader and instance class) and one entry in :data:`KINDS`.
"""

from __future__ import annotations

import importlib
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, NamedTuple

__all__ = ["KINDS", "Kind", "LifeCycle", "kind_of", "life_cycle", "versions"]


class LifeCycle(NamedTuple):
    """A version's functions for each step of the life cycle (noted for a supervisor, named in errors)."""

    instantiate: str
    enter_initialization_mode: str
    exit_initialization_mode: str
    enter_event_mode: str
    update_discrete_states: str
    enter_continuous_time_mode: str
    completed_integrator_step: str
    get_nominals: str
    terminate: str
    reset: str
    free_instance: str


@dataclass(frozen=True)
class Kind:
    """One FMI version and interface: what the master calls differently for it."""

    version: str  # modelDescription.xml's fmiVersion
    co_simulation: bool  # the interface: Co-Simulation (a sampled component) or Model Exchange
    reader: str  # "module:function" reading the description: (path, fmpy's description, kind) -> FMUInfo
    instance: str  # "module:Class" of its instances
    #: the functions its binary must export
    required_functions: tuple[str, ...]
    #: its life-cycle functions (Model Exchange)
    life: LifeCycle | None = None
    #: its own name of each fmi2-shaped call the master notes for a supervisor (watch.FUNCTIONS)
    call_names: Mapping[str, str] = field(default_factory=dict)
    #: whether the compiled kernel's events (fast_events.hs_event, FMI 2.0's calls) take it
    fast_events: bool = False

    @property
    def interface(self) -> str:
        return "Co-Simulation" if self.co_simulation else "Model Exchange"

    def instance_class(self) -> Any:
        """The class of this kind's instances (imported at first use: instance modules import the registry)."""
        return _load(self.instance)

    def read(self, path: Any, description: Any) -> Any:
        """The :class:`~heliostep.cosim.description.FMUInfo` of an FMU of this kind read by fmpy (``description``)."""
        return _load(self.reader)(path, description, self)

    @property
    def update_function(self) -> str:
        """The event iteration's function, named when an FMU asks to terminate there."""
        return self.life.update_discrete_states if self.life is not None else ""

    def own_name(self, call: str) -> str:
        """This kind's name of the fmi2-shaped ``call`` noted for a supervisor."""
        return self.call_names.get(call, call)


def _load(where: str) -> Any:
    module, name = where.split(":")
    return getattr(importlib.import_module(module), name)


#: The functions an FMI 2.0 binary must export for both interfaces, then Model Exchange's and Co-Simulation's.
_FMI2_COMMON = (
    "fmi2GetTypesPlatform",
    "fmi2GetVersion",
    "fmi2SetDebugLogging",
    "fmi2Instantiate",
    "fmi2FreeInstance",
    "fmi2SetupExperiment",
    "fmi2EnterInitializationMode",
    "fmi2ExitInitializationMode",
    "fmi2Terminate",
    "fmi2Reset",
    "fmi2GetReal",
    "fmi2GetInteger",
    "fmi2GetBoolean",
    "fmi2GetString",
    "fmi2SetReal",
    "fmi2SetInteger",
    "fmi2SetBoolean",
    "fmi2SetString",
)
_FMI2_MODEL_EXCHANGE = (
    "fmi2EnterEventMode",
    "fmi2NewDiscreteStates",
    "fmi2EnterContinuousTimeMode",
    "fmi2CompletedIntegratorStep",
    "fmi2SetTime",
    "fmi2SetContinuousStates",
    "fmi2GetDerivatives",
    "fmi2GetEventIndicators",
    "fmi2GetContinuousStates",
    "fmi2GetNominalsOfContinuousStates",
)

#: An FMI 3.0 FMU's own function for each fmi2-shaped call (the adapter of heliostep.cosim.fmi3 makes
#: them of these); its integer calls go through the getter or setter of the variable's own type.
_FMI3_CALL_NAMES = {
    "fmi2SetTime": "fmi3SetTime",
    "fmi2SetContinuousStates": "fmi3SetContinuousStates",
    "fmi2GetContinuousStates": "fmi3GetContinuousStates",
    "fmi2GetReal": "fmi3GetFloat64",
    "fmi2SetReal": "fmi3SetFloat64",
    "fmi2GetDerivatives": "fmi3GetContinuousStateDerivatives",
    "fmi2GetEventIndicators": "fmi3GetEventIndicators",
    "fmi2GetInteger": "an fmi3Get function of an integer type",
    "fmi2SetInteger": "an fmi3Set function of an integer type",
    "fmi2GetBoolean": "fmi3GetBoolean",
    "fmi2SetBoolean": "fmi3SetBoolean",
    "fmi2GetString": "fmi3GetString",
    "fmi2SetString": "fmi3SetString",
}

KINDS: tuple[Kind, ...] = (
    Kind(
        "2.0",
        False,
        "heliostep.cosim.description:read_fmi2",
        "heliostep.cosim.fmi:ModelExchangeInstance",
        _FMI2_COMMON + _FMI2_MODEL_EXCHANGE,
        life=LifeCycle(
            "fmi2Instantiate",
            "fmi2EnterInitializationMode",
            "fmi2ExitInitializationMode",
            "fmi2EnterEventMode",
            "fmi2NewDiscreteStates",
            "fmi2EnterContinuousTimeMode",
            "fmi2CompletedIntegratorStep",
            "fmi2GetNominalsOfContinuousStates",
            "fmi2Terminate",
            "fmi2Reset",
            "fmi2FreeInstance",
        ),
        fast_events=True,
    ),
    Kind(
        "2.0",
        True,
        "heliostep.cosim.description:read_fmi2",
        "heliostep.cosim.sampled:CoSimulationInstance",
        (*_FMI2_COMMON, "fmi2DoStep"),
    ),
    Kind(
        "3.0",
        False,
        "heliostep.cosim.description3:read_fmi3",
        "heliostep.cosim.fmi3:ModelExchange3Instance",
        (
            "fmi3GetVersion",
            "fmi3InstantiateModelExchange",
            "fmi3FreeInstance",
            "fmi3EnterInitializationMode",
            "fmi3ExitInitializationMode",
            "fmi3Terminate",
            "fmi3Reset",
            "fmi3GetFloat64",
            "fmi3SetFloat64",
            "fmi3GetInt32",
            "fmi3SetInt32",
            "fmi3GetBoolean",
            "fmi3SetBoolean",
            "fmi3EnterEventMode",
            "fmi3UpdateDiscreteStates",
            "fmi3EnterContinuousTimeMode",
            "fmi3CompletedIntegratorStep",
            "fmi3SetTime",
            "fmi3SetContinuousStates",
            "fmi3GetContinuousStateDerivatives",
            "fmi3GetEventIndicators",
            "fmi3GetContinuousStates",
            "fmi3GetNominalsOfContinuousStates",
        ),
        life=LifeCycle(
            "fmi3InstantiateModelExchange",
            "fmi3EnterInitializationMode",
            "fmi3ExitInitializationMode",
            "fmi3EnterEventMode",
            "fmi3UpdateDiscreteStates",
            "fmi3EnterContinuousTimeMode",
            "fmi3CompletedIntegratorStep",
            "fmi3GetNominalsOfContinuousStates",
            "fmi3Terminate",
            "fmi3Reset",
            "fmi3FreeInstance",
        ),
        call_names=_FMI3_CALL_NAMES,
    ),
    Kind(
        "3.0",
        True,
        "heliostep.cosim.description3:read_fmi3",
        "heliostep.cosim.sampled3:CoSimulation3Instance",
        (
            "fmi3GetVersion",
            "fmi3InstantiateCoSimulation",
            "fmi3FreeInstance",
            "fmi3EnterInitializationMode",
            "fmi3ExitInitializationMode",
            "fmi3Terminate",
            "fmi3GetFloat64",
            "fmi3SetFloat64",
            "fmi3DoStep",
        ),
    ),
)

_BY_KEY = {(kind.version, kind.co_simulation): kind for kind in KINDS}


def kind_of(version: str, co_simulation: bool = False) -> Kind | None:
    """The kind of an FMU of FMI ``version`` read for Co-Simulation or Model Exchange; None: not one heliostep runs."""
    return _BY_KEY.get((version, co_simulation))


def versions() -> str:
    """The FMI versions heliostep runs, for a message: "2.0 or 3.0"."""
    return " or ".join(sorted({kind.version for kind in KINDS}))


def life_cycle(version: str) -> LifeCycle:
    """The life-cycle functions of FMI ``version``'s Model Exchange instances."""
    kind = kind_of(version)
    assert kind is not None and kind.life is not None
    return kind.life
