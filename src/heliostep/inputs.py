"""From a scenario to what the master consumes: reference, step schedule, input signals, grid.

This is the second stage of heliostep's one-way data flow
(scenario → **inputs** → master → trace → summary / plots / compare):

1. the reference panel angle of the scenario's mirror and axis over the window, from the
   sun's position (pvlib SPA, :mod:`heliostep.geometry`) on a grid of at most 10 s;
2. the reference rotor angle through the transmission law ([paper], eqs. 12–14), 0 at the
   window start as in the paper;
3. the step instants where that reference crosses half-step boundaries
   (:func:`heliostep.sequencer.schedule_steps`, exact roots of a monotone interpolant);
4. the master-side input signals: the sequencer's reference currents (piecewise constant,
   changing at the steps) and the wind moment;
5. the output grid: regular, plus a finer grid for a while after each step.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd
from scipy.interpolate import PchipInterpolator

from heliostep.geometry import panel_angle_reference, rotor_angle_from_panel
from heliostep.master import PiecewiseConstant
from heliostep.scenario import Scenario
from heliostep.sequencer import Sequencer, StepSchedule, reference_interpolant, schedule_steps

#: Longest spacing of the grid on which the sun's position is evaluated [s].
MAX_REFERENCE_SPACING = 10.0

#: FMU inputs the drive's master signals feed (instance.variable).
MOTOR_CURRENT_INPUTS = ("motor.i_a_ref", "motor.i_b_ref")
WIND_INPUT = "mechanics.m_ext"


@dataclass(frozen=True)
class DriveInputs:
    """Everything the master needs for one scenario, computed from it alone."""

    window_start: pd.Timestamp
    duration: float
    reference_times: np.ndarray
    panel_angle_ref: np.ndarray
    rotor_angle_ref: np.ndarray
    sequencer: Sequencer
    schedule: StepSchedule
    signals: tuple[PiecewiseConstant, ...]
    output_times: np.ndarray
    #: mechanics parameters implied by the scenario (initial panel angle, transmission)
    mechanics_parameters: dict = field(default_factory=dict)
    #: motor parameters implied by the scenario (the drive holds its first step at the start)
    motor_parameters: dict = field(default_factory=dict)

    def panel_reference(self) -> PchipInterpolator:
        """Reference panel angle [rad] over time [s] (the same interpolation as the steps)."""
        return PchipInterpolator(self.reference_times, self.panel_angle_ref, extrapolate=True)

    def rotor_reference(self) -> PchipInterpolator:
        """Reference rotor angle [rad] over time [s]."""
        return PchipInterpolator(self.reference_times, self.rotor_angle_ref, extrapolate=True)


def reference_times(duration: float) -> np.ndarray:
    """Times [s] at which the sun is evaluated: at least 600 points, at most 10 s apart."""
    n = max(600, int(np.ceil(duration / MAX_REFERENCE_SPACING)) + 1)
    return np.linspace(0.0, duration, n)


def output_grid(duration: float, interval: float, step_times: np.ndarray,
                step_detail: float, step_interval: float) -> np.ndarray:
    """Regular grid plus, after each step, ``step_detail`` seconds at ``step_interval`` [s]."""
    regular = np.arange(0.0, duration, interval)
    detail = np.arange(0.0, step_detail, step_interval)
    fine = (step_times[:, None] + detail[None, :]).ravel() if len(step_times) else np.zeros(0)
    grid = np.concatenate([regular, fine, [duration]])
    return np.unique(grid[(grid >= 0.0) & (grid <= duration)])


def prepare_inputs(scenario: Scenario, fmu_inputs: frozenset[str] = frozenset()) -> DriveInputs:
    """Compute the reference, the step schedule, the master's input signals and the grid.

    ``fmu_inputs`` names the inputs (``instance.variable``) the scenario's FMUs have: the
    wind moment feeds ``mechanics.m_ext`` when that input exists (a non-zero moment with no
    such input is an error from the master, naming it).
    """
    start, end = scenario.window_bounds()
    duration = (end - start).total_seconds()
    times = reference_times(duration)
    index = start + pd.to_timedelta(times, unit="s")
    mirror = scenario.mirror
    panel = panel_angle_reference(
        index, scenario.site.to_site(), scenario.plant.to_plant(), mirror.mirror_distance,
        axis=mirror.axis, stow=mirror.stow, stow_angle=np.radians(mirror.stow_angle)).to_numpy()
    transmission = scenario.transmission
    rotor = rotor_angle_from_panel(panel, panel[0], transmission.pinion_radius, transmission.lever_arm,
                                   rotor_angle0=0.0)  # [paper], eq. 14, rotor at 0 at the start
    sequencer = Sequencer(mode=scenario.sequencer.mode, current=scenario.sequencer.current,
                          step_angle=np.radians(scenario.sequencer.step_angle))
    schedule = schedule_steps(reference_interpolant(times, np.asarray(rotor)), sequencer,
                              trigger=scenario.sequencer.trigger)

    indices = np.concatenate([[schedule.initial_index], schedule.indices])
    i_a_ref, i_b_ref = sequencer.reference_currents(indices)
    signals = [
        PiecewiseConstant("i_a_ref", MOTOR_CURRENT_INPUTS[0], schedule.times, i_a_ref),
        PiecewiseConstant("i_b_ref", MOTOR_CURRENT_INPUTS[1], schedule.times, i_b_ref),
    ]
    if scenario.wind.moment != 0.0 or WIND_INPUT in fmu_inputs:
        signals.append(PiecewiseConstant("m_ext", WIND_INPUT, np.zeros(0), np.array([scenario.wind.moment])))

    out = scenario.output
    grid = output_grid(duration, out.interval, schedule.times, out.step_detail, out.step_interval)
    mechanics = {"theta_p_start": float(panel[0]), "theta_start": 0.0,
                 "r": transmission.pinion_radius, "s": transmission.lever_arm}
    motor = {"i_a_start": float(i_a_ref[0]), "i_b_start": float(i_b_ref[0])}
    return DriveInputs(window_start=start, duration=duration, reference_times=times,
                       panel_angle_ref=np.asarray(panel, dtype=float), rotor_angle_ref=np.asarray(rotor, dtype=float),
                       sequencer=sequencer, schedule=schedule, signals=tuple(signals),
                       output_times=grid, mechanics_parameters=mechanics, motor_parameters=motor)

