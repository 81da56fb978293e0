"""What heliostep reads of an FMI 3.0 FMU: the same :class:`~heliostep.cosim.description.FMUInfo` as FMI 2.0's.

Array variables are read element by element (``a[1,2]``, :mod:`~heliostep.cosim.fmi3_types`); what the
master does not run (Scheduled Execution, clocks, Co-Simulation only unless asked for) is refused up front
with :class:`~heliostep.errors.InputError` naming the FMU and the feature.
"""

from __future__ import annotations

from pathlib import Path

from heliostep.cosim.description import FMUInfo, VariableInfo, check_binary
from heliostep.cosim.fmi3_types import fmi3_variables
from heliostep.cosim.kinds import Kind
from heliostep.errors import InputError

__all__ = ["read_fmi3"]


def read_fmi3(path: Path, description, kind: Kind) -> FMUInfo:
    """An FMI 3.0 FMU read by fmpy (``description``) as the master's :class:`FMUInfo` of ``kind``, or
    :class:`InputError` naming ``path`` and the feature heliostep does not support."""
    from fmpy import platform_tuple

    interface = description.coSimulation if kind.co_simulation else description.modelExchange
    if interface is None:
        _refuse_interface(path, description, kind.co_simulation)
    _refuse_unsupported(path, description)
    check_binary(path, interface.modelIdentifier, kind, platform_tuple)
    fields, states, n_indicators, feedthrough = fmi3_variables(description)
    variables = {name: VariableInfo(**values) for name, values in fields.items()}
    return FMUInfo(
        path=path,
        model_name=description.modelName,
        model_identifier=interface.modelIdentifier,
        guid=description.instantiationToken or description.guid or "",
        variables=variables,
        states=states,
        n_event_indicators=n_indicators,
        output_feedthrough=feedthrough,
        needs_completed_integrator_step=bool(getattr(interface, "needsCompletedIntegratorStep", False)),
        description=description,
        co_simulation=kind.co_simulation,
        fmi_version=kind.version,
    )


def _refuse_interface(path: Path, description, co_simulation: bool) -> None:
    """The interface asked for is missing: an InputError saying what the FMU offers and what to do."""
    if co_simulation:
        raise InputError(f"{path}: the FMU does not support Co-Simulation, but communication_interval asks for it")
    if description.coSimulation is not None:
        raise InputError(
            f"{path}: FMI 3.0 Co-Simulation only (no Model Exchange); heliostep integrates Model Exchange FMUs "
            "itself, or runs a Co-Simulation FMU as a sampled component: give its instance a communication_interval "
            "(docs/fmus.md)"
        )
    offered = "Scheduled Execution" if getattr(description, "scheduledExecution", None) is not None else "no interface"
    raise InputError(
        f"{path}: FMI 3.0 {offered}: heliostep runs FMI 3.0 FMUs through Model Exchange, or Co-Simulation as a "
        "sampled component (FMI 3.0 Scheduled Execution is not supported)"
    )


def _refuse_unsupported(path: Path, description) -> None:
    """Clocks and clocked variables (the master has no clocked partitions)."""
    for v in description.modelVariables:
        if v.type == "Clock" or getattr(v, "clocks", None):
            raise InputError(
                f"{path}: FMI 3.0 clocks ({'clock' if v.type == 'Clock' else 'clocked variable'} {v.name!r}) are "
                "not supported by heliostep's master"
            )
