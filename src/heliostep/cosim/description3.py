"""What heliostep reads of an FMI 3.0 FMU: its Model Exchange interface, variables and refusals.

:func:`read_fmu3` turns fmpy's reading of an FMI 3.0 ``modelDescription.xml`` into the same
:class:`~heliostep.cosim.description.FMUInfo` as an FMI 2.0 FMU's (``fmi_version`` "3.0"), so the
master, the connections and the compiled kernel treat both alike. The FMI 3.0 types the master
exchanges map onto FMI 2.0's: Float64 is "Real", Int32 "Integer", Boolean "Boolean" (their calls
go through the adapter of :mod:`heliostep.cosim.fmi3`). Parameters and local variables may have
any FMI 3.0 type. What the master does not support is refused up front with
:class:`~heliostep.errors.InputError` naming the FMU and the feature: Co-Simulation or Scheduled
Execution only, clocks (and clocked variables), array variables, and inputs or outputs of a type
other than Float64, Int32 and Boolean (Float32, Int8 ... UInt64, Enumeration, String, Binary).
"""

from __future__ import annotations

from pathlib import Path

from heliostep.cosim.description import FMUInfo, VariableInfo, _check_binary, _parse_start, _unit
from heliostep.errors import InputError

#: FMI 3.0 type -> the master's type name (FMI 2.0's where the kernel exchanges it)
_TYPE_NAMES = {"Float64": "Real", "Int32": "Integer", "Boolean": "Boolean"}

#: The functions every FMI 3.0 Model Exchange binary must export that heliostep calls.
REQUIRED_FUNCTIONS3 = (
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
)


def read_fmu3(path: Path, description, co_simulation: bool = False) -> FMUInfo:
    """An FMI 3.0 FMU read by fmpy (``description``) as the master's :class:`FMUInfo`, or
    :class:`InputError` naming ``path`` and the feature heliostep does not support."""
    from fmpy import platform_tuple

    if co_simulation or description.modelExchange is None:
        offered = [
            kind
            for kind, interface in (
                ("Co-Simulation", description.coSimulation),
                ("Scheduled Execution", getattr(description, "scheduledExecution", None)),
            )
            if interface is not None
        ]
        raise InputError(
            f"{path}: FMI 3.0 {' and '.join(offered) or 'without Model Exchange'}: heliostep runs FMI 3.0 FMUs "
            "through Model Exchange only (FMI 3.0 Co-Simulation and Scheduled Execution are not supported)"
        )
    _refuse_unsupported(path, description)
    interface = description.modelExchange
    _check_binary(path, interface.modelIdentifier, REQUIRED_FUNCTIONS3, platform_tuple)
    variables = {
        v.name: VariableInfo(
            name=v.name,
            value_reference=v.valueReference,
            type=_TYPE_NAMES.get(v.type, v.type),
            causality=v.causality,
            variability=v.variability,
            unit=_unit(v),
            start=None if v.start is None else _parse_start(_TYPE_NAMES.get(v.type, v.type), v.start),
            description=v.description or "",
        )
        for v in description.modelVariables
    }
    inputs = {v.name for v in description.modelVariables if v.causality == "input"}
    feedthrough = {}
    for unknown in description.outputs:
        dependencies = unknown.dependencies
        names = sorted(inputs) if dependencies is None else [d.name for d in dependencies if d.name in inputs]
        feedthrough[unknown.variable.name] = names
    return FMUInfo(
        path=path,
        model_name=description.modelName,
        model_identifier=interface.modelIdentifier,
        guid=description.instantiationToken or description.guid or "",
        variables=variables,
        states=[d.variable.derivative.name for d in description.derivatives],
        n_event_indicators=len(description.eventIndicators or []),
        output_feedthrough=feedthrough,
        needs_completed_integrator_step=bool(getattr(interface, "needsCompletedIntegratorStep", False)),
        description=description,
        fmi_version="3.0",
    )


def _refuse_unsupported(path: Path, description) -> None:
    """Clocks, clocked variables, arrays, and inputs/outputs of a type the master cannot exchange."""
    for v in description.modelVariables:
        if v.type == "Clock" or getattr(v, "clocks", None):
            raise InputError(
                f"{path}: FMI 3.0 clocks ({'clock' if v.type == 'Clock' else 'clocked variable'} {v.name!r}) are "
                "not supported by heliostep's master"
            )
        if getattr(v, "dimensions", None):
            raise InputError(
                f"{path}: FMI 3.0 array variable {v.name!r} ({v.type}): array variables are not supported yet"
            )
        if v.causality in ("input", "output") and v.type not in _TYPE_NAMES:
            raise InputError(
                f"{path}: FMI 3.0 {v.causality} {v.name!r} of type {v.type}: heliostep exchanges and traces FMI 3.0 "
                f"inputs and outputs of type {', '.join(_TYPE_NAMES)} only (other types as parameters or locals)"
            )
