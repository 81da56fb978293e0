"""A run's bindings: the scenario's roles, parameters and drive signals onto its FMUs.

The FMU variables each part of the drive uses are found through the scenario's roles, checked
against the FMUs (:class:`~heliostep.cosim.FMUInfo`) and resolved once per run; the drive's
commands become the master's input signals (:class:`~heliostep.cosim.PiecewiseConstant`). Here,
in the run layer, because :mod:`heliostep.drive` never imports :mod:`heliostep.cosim`.
"""

from __future__ import annotations

import numpy as np

from heliostep.cosim import FMUInfo, PiecewiseConstant
from heliostep.drive.inputs import DriveInputs
from heliostep.drive.sequencer import idle_currents, stuck_currents
from heliostep.errors import InputError
from heliostep.run.interface import check_interface
from heliostep.scenario import INPUT_ROLES, OUTPUT_ROLES, PARAMETER_ROLES, REQUIRED_ROLES, Scenario

__all__ = ["check_roles", "parameters", "present_roles", "signals"]


def check_roles(roles: dict[str, str], infos: dict[str, FMUInfo], scenario: Scenario) -> None:
    """Every role names a variable its FMU has, with the right causality."""
    expected = {
        **{r: "input" for r in INPUT_ROLES},
        **{r: "output" for r in OUTPUT_ROLES},
        **{r: "parameter" for r in PARAMETER_ROLES},
    }
    for role, target in roles.items():
        instance, _, variable = target.partition(".")
        info = infos[instance]
        if variable not in info.variables:
            if role not in scenario.roles.model_fields_set:
                continue  # a default role this FMU does not have: absent
            raise InputError(
                f"{scenario.source}: roles.{role}: {info.path.name} (instance {instance!r}) has no "
                f"variable {variable!r}; its {expected[role]}s: {', '.join(info.names(expected[role]))}"
            )
        causality = info.variables[variable].causality
        if causality != expected[role]:
            raise InputError(
                f"{scenario.source}: roles.{role}: {target} has causality {causality!r}, expected {expected[role]!r}"
            )


def present_roles(scenario: Scenario, infos: dict[str, FMUInfo]) -> dict[str, str]:
    """The scenario's roles that exist in its FMUs (checked), resolved once for the whole run."""
    roles = scenario.resolved_roles()
    check_roles(roles, infos, scenario)
    check_interface(scenario, infos)  # a default connection or required role that names no variable
    present = {
        role: target
        for role, target in roles.items()
        if target.partition(".")[2] in infos[target.partition(".")[0]].variables
    }
    missing = [role for role in REQUIRED_ROLES if role not in present]
    if missing:  # check_interface refuses these first; kept so that no later change lets one through
        raise InputError(f"{scenario.source}: roles {', '.join(missing)} name no variable of the FMUs")
    return present


def parameters(scenario: Scenario, inputs: DriveInputs, roles: dict[str, str], infos: dict[str, FMUInfo]) -> dict:
    """Parameters per instance: what the scenario implies (through the parameter roles), then the user's."""
    values = {name: dict(scenario.parameters.get(name, {})) for name in infos}
    transmission_keys = {"pinion_radius": "transmission.pinion_radius", "lever_arm": "transmission.lever_arm"}
    for role, value in inputs.implied_parameters.items():
        if role not in roles:
            continue
        instance, _, name = roles[role].partition(".")
        user = scenario.parameters.get(instance, {})
        if role in transmission_keys and name in user and user[name] != value:
            raise InputError(
                f"{scenario.source}: parameters.{instance}.{name} = {user[name]} contradicts "
                f"{transmission_keys[role]} = {value}; set the transmission in "
                f"{transmission_keys[role]} only"
            )
        values[instance].setdefault(name, value)
    return values


def signals(
    inputs: DriveInputs, roles: dict[str, str], stuck: tuple[float, float] | None = None
) -> list[PiecewiseConstant]:
    """The drive's commands as the master's input signals, into the FMU inputs their roles name.

    With idle current reduction the currents also drop to their idle fraction a set time after
    each step (:func:`heliostep.drive.sequencer.idle_currents`); those instants are events too. A driver
    ``stuck`` over (start, end) [s] ignores the changes meanwhile (:func:`~heliostep.drive.sequencer.stuck_currents`).
    """
    steps, current_a, current_b = inputs.schedule.times, inputs.current_a_ref, inputs.current_b_ref
    if inputs.sequencer.idle_current_fraction != 1.0:
        times, current_a, current_b = idle_currents(inputs.schedule, inputs.sequencer, inputs.duration)
        steps = np.asarray(times[1:], dtype=float)
    steps, (current_a, current_b) = stuck_currents(steps, [current_a, current_b], stuck)
    result = [
        PiecewiseConstant("i_a_ref", roles["current_a_ref"], steps, np.asarray(current_a, dtype=float)),
        PiecewiseConstant("i_b_ref", roles["current_b_ref"], steps, np.asarray(current_b, dtype=float)),
    ]
    wind = inputs.wind_signal
    if "wind_moment" in roles and wind is not None:  # the wind's moment over the window (drive.wind_load)
        result.append(PiecewiseConstant("m_ext", roles["wind_moment"], wind.times, wind.values))
    elif "wind_moment" in roles:
        result.append(PiecewiseConstant("m_ext", roles["wind_moment"], np.zeros(0), np.array([inputs.wind_moment])))
    elif wind is not None:
        raise InputError("wind: a wind speed is given, but no FMU input has the role wind_moment (roles.wind_moment)")
    elif inputs.wind_moment != 0.0:
        raise InputError(
            f"wind.moment = {inputs.wind_moment} N.m, but no FMU input has the role wind_moment (roles.wind_moment)"
        )
    return result
