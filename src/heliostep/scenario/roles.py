"""Roles: which FMU variable plays which part in the drive, so no instance name is hard-wired.

Details: docs/running.md, ``heliostep.scenario.roles``.
"""

from __future__ import annotations

from pydantic import Field

from heliostep.scenario.sections import Section

#: Roles of FMU *inputs* driven by the master (the sequencer and the wind).
INPUT_ROLES = ("current_a_ref", "current_b_ref", "wind_moment")
#: Roles of FMU *outputs* that the trace, the summary and the plots use.
OUTPUT_ROLES = ("torque", "current_a", "current_b", "power", "rotor_angle", "panel_angle")
#: Roles of FMU *parameters* the scenario implies (the drive holds its first step at the start).
PARAMETER_ROLES = (
    "panel_angle_start",
    "rotor_angle_start",
    "pinion_radius",
    "lever_arm",
    "current_a_start",
    "current_b_start",
)
#: Roles a run cannot do without.
REQUIRED_ROLES = ("current_a_ref", "current_b_ref", "rotor_angle")


def _role(default: str, what: str):
    return Field(default, description=f"'instance.variable' of {what}; null: none")


class RolesConfig(Section):
    """``roles``: role -> ``instance.variable`` (defaults: the shipped FMUs' interface)."""

    current_a_ref: str | None = _role("motor.i_a_ref", "the phase A reference current input [A]")
    current_b_ref: str | None = _role("motor.i_b_ref", "the phase B reference current input [A]")
    wind_moment: str | None = _role("mechanics.m_ext", "the external moment input on the panel [N.m]")
    torque: str | None = _role("motor.tau", "the motor torque output [N.m]")
    current_a: str | None = _role("motor.i_a", "the phase A current output [A]")
    current_b: str | None = _role("motor.i_b", "the phase B current output [A]")
    power: str | None = _role("motor.power", "the electrical power output [W]")
    rotor_angle: str | None = _role("mechanics.theta", "the rotor angle output [rad]")
    panel_angle: str | None = _role("mechanics.theta_p", "the panel angle output [rad]")
    panel_angle_start: str | None = _role("mechanics.theta_p_start", "the initial panel angle parameter [rad]")
    rotor_angle_start: str | None = _role("mechanics.theta_start", "the initial rotor angle parameter [rad]")
    pinion_radius: str | None = _role("mechanics.r", "the pinion radius parameter [m]")
    lever_arm: str | None = _role("mechanics.s", "the lever arm parameter [m]")
    current_a_start: str | None = _role("motor.i_a_start", "the initial phase A current parameter [A]")
    current_b_start: str | None = _role("motor.i_b_start", "the initial phase B current parameter [A]")

    def present(self) -> dict[str, str]:
        """Role -> ``instance.variable`` of every role that is set."""
        return {name: value for name, value in self.model_dump().items() if value is not None}

    def instance_of(self, role: str) -> str | None:
        """The FMU instance a role lives in (None when the role is absent)."""
        target = getattr(self, role)
        return None if target is None else target.partition(".")[0]
