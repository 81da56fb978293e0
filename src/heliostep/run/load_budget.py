"""The load a drive must carry and the torque its motor has against it: the sizing's two sides.

The load on the motor shaft at each instant of a scenario's window ([paper], eqs. 10 and 15, with the
exact ratio g = s/(r cos^2 theta_p)):

* wind: M / g, the moment on the panel axis reflected through the rack and pinion;
* friction: T_c + M_c / g, the Coulomb friction of reducer and rack on the shaft and of the hinge
  bearings on the panel axis (the mechanics FMU's parameters);
* inertia: (J_m + J_p / g^2) |d^2 theta_ref / dt^2|, the torque to follow the reference's fastest
  change of speed (while tracking this is tiny: the sun moves slowly; a slew move's would be larger).

:class:`LoadBudget` is the worst instant's. Against it, :func:`static_step_limit` is the largest static
load the motor steps against without slipping, from the static torque curves ([paper], eq. 9): a step
moves the stable position by an electrical angle Delta; a rotor held at lag delta behind its detent
(A_from sin delta = T) feels A_to sin(Delta + delta) towards the next one, which must exceed T. One
phase on, full steps: T_max = T_hold cos(pi/4) = 0.707 T_hold (the adjacent detents' curves cross
there); microsteps m: T_hold cos(pi/(4m)); two phases on: sqrt(2) T_hold cos(pi/4) = T_hold.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import asdict, dataclass

import numpy as np

from heliostep.drive.inputs import DriveInputs
from heliostep.scenario import Scenario
from heliostep.scenario.catalogue import MotorDrive

__all__ = ["LoadBudget", "load_budget", "static_step_limit", "wind_moment_at"]


@dataclass(frozen=True)
class LoadBudget:
    """The load on the motor shaft at the window's worst instant [N.m], and where it is."""

    wind_Nm: float
    friction_Nm: float
    inertia_Nm: float
    total_Nm: float
    time_s: float  # the worst instant, from the window's start
    panel_angle_deg: float
    ratio: float  # g = d theta / d theta_p there
    wind_moment_Nm: float  # on the panel axis
    max_step_rate_per_s: float  # the reference's fastest rotor speed, in full steps per second

    def record(self) -> dict:
        return asdict(self)


def load_budget(
    scenario: Scenario,
    inputs: DriveInputs,
    wind_moment: float | np.ndarray,
    mechanics: Mapping[str, float],
    rotor_inertia: float,
) -> LoadBudget:
    """The load budget over ``inputs``' reference.

    Parameters
    ----------
    wind_moment : float or array
        The design moment on the panel axis [N.m], or the moment at each of ``inputs.reference_times``
        (the wind over time, :func:`wind_moment_at`).
    mechanics : mapping
        The mechanics FMU's ``T_c`` [N.m], ``M_c`` [N.m] and ``J_p`` [kg.m2] (its defaults with the
        scenario's values over them).
    rotor_inertia : float
        J_m [kg.m2], the candidate's.
    """
    transmission = scenario.transmission
    times, panel = inputs.reference_times, inputs.panel_angle_ref
    ratio = transmission.lever_arm / (transmission.pinion_radius * np.cos(panel) ** 2)
    rotor = inputs.rotor_reference()
    acceleration = np.abs(rotor.derivative(2)(times))
    speed = np.abs(rotor.derivative(1)(times))
    wind = abs(wind_moment) / ratio
    friction = mechanics["T_c"] + mechanics["M_c"] / ratio
    inertia = (rotor_inertia + mechanics["J_p"] / ratio**2) * acceleration
    total = wind + friction + inertia
    worst = int(np.argmax(total))
    return LoadBudget(
        wind_Nm=float(wind[worst]),
        friction_Nm=float(friction[worst]),
        inertia_Nm=float(inertia[worst]),
        total_Nm=float(total[worst]),
        time_s=float(times[worst]),
        panel_angle_deg=float(np.degrees(panel[worst])),
        ratio=float(ratio[worst]),
        wind_moment_Nm=float(np.broadcast_to(wind_moment, np.shape(times))[worst]),
        max_step_rate_per_s=float(np.max(speed) / inputs.sequencer.step_angle),
    )


def wind_moment_at(inputs: DriveInputs) -> np.ndarray:
    """The wind's moment on the panel axis [N.m] at each reference instant: the ``m_ext`` signal held
    there (``values[0]`` before ``times[0]``, ``values[k + 1]`` from ``times[k]`` on; its sign turned back,
    m_ext = -M), or the constant ``wind_moment`` without a wind speed."""
    signal, times = inputs.wind_signal, inputs.reference_times
    if signal is None:
        return np.full(np.shape(times), float(inputs.wind_moment))
    return -np.asarray(signal.values)[np.searchsorted(signal.times, times, side="right")]


def _transition_limit(a_from: float, a_to: float, delta: float) -> float:
    """The largest static load T with a_to sin(delta + asin(T / a_from)) >= T (bisection) [N.m]."""
    low, high = 0.0, min(a_from, a_to)
    for _ in range(60):
        load = 0.5 * (low + high)
        if a_to * math.sin(delta + math.asin(load / a_from)) >= load:
            low = load
        else:
            high = load
    return low


def static_step_limit(drive: MotorDrive, current: float, mode: str = "one-phase-on", microsteps: int = 1) -> float:
    """The largest static load on the shaft [N.m] against which a step is taken from rest (module docstring)."""
    held = drive.holding_torque(current)
    if microsteps > 1:
        return _transition_limit(held, held, math.pi / (2 * microsteps))
    if mode == "two-phase-on":
        return _transition_limit(math.sqrt(2.0) * held, math.sqrt(2.0) * held, math.pi / 2)
    if mode == "half-step":
        one, two = held, math.sqrt(2.0) * held
        return min(_transition_limit(one, two, math.pi / 4), _transition_limit(two, one, math.pi / 4))
    return _transition_limit(held, held, math.pi / 2)
