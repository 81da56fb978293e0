"""The shipped drive as two connected FMUs, for the master's tests: its connections, a step
pattern (forward three steps, back two) and the sequencer's phase currents for it."""

from __future__ import annotations

import numpy as np

from heliostep.cosim.master import Connection, PiecewiseConstant
from heliostep.drive.sequencer import Sequencer

#: The motor's torque to the mechanics, the mechanics' angle and speed back to the motor.
DRIVE_CONNECTIONS = [
    Connection("motor.tau", "mechanics.tau"),
    Connection("mechanics.theta", "motor.theta"),
    Connection("mechanics.omega", "motor.omega"),
]
STEP_TIMES = np.array([0.05, 0.15, 0.25, 0.35, 0.45])  # [s]
STEP_INDICES = np.array([0, 1, 2, 3, 2, 1])  # forward three steps, back two


def current_inputs(prefix: str = "motor") -> list[PiecewiseConstant]:
    """The phase-current references of :data:`STEP_INDICES` switched at :data:`STEP_TIMES`, into ``prefix``'s inputs."""
    i_a, i_b = Sequencer().reference_currents(STEP_INDICES)
    return [
        PiecewiseConstant("i_a_ref", f"{prefix}.i_a_ref", STEP_TIMES, i_a),
        PiecewiseConstant("i_b_ref", f"{prefix}.i_b_ref", STEP_TIMES, i_b),
    ]
