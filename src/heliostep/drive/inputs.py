"""From a scenario to what the drive commands: reference, step schedule, phase currents, grid.

Details: docs/physics.md, ``heliostep.drive.inputs``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pandas as pd
from scipy.interpolate import PchipInterpolator

from heliostep.drive.sequencer import (
    Sequencer,
    StepSchedule,
    reference_interpolant,
    schedule_steps,
)
from heliostep.drive.stow import StowMove, StowPlan, plan_stow, stowed_spans
from heliostep.drive.wind_load import WindKnots, WindSignal, commanded_panel_angle, moment_signal, wind_speed_knots
from heliostep.errors import InputError
from heliostep.scenario import Scenario
from heliostep.solar import panel_angle_reference, rotor_angle_from_panel

#: Longest spacing of the grid on which the sun's position is evaluated [s].
MAX_REFERENCE_SPACING = 10.0


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
    #: reference phase currents [A]: before the first step, then from each step on
    current_a_ref: np.ndarray
    current_b_ref: np.ndarray
    #: constant external moment on the panel [N.m]
    wind_moment: float
    output_times: np.ndarray
    #: parameter values the scenario implies, by role (initial panel and rotor angle,
    #: transmission, initial phase currents: the drive holds its first step at the start)
    implied_parameters: dict = field(default_factory=dict)
    #: the wind's moment signal and speed (None: the constant ``wind_moment``)
    wind_signal: WindSignal | None = None
    #: the stow and return moves, and the spans off tracking (start, end) [s]
    stow_moves: tuple[StowMove, ...] = ()
    stowed_spans: tuple[tuple[float, float], ...] = ()

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


def output_grid(
    duration: float, interval: float, step_times: np.ndarray, step_detail: float, step_interval: float
) -> np.ndarray:
    """Regular grid plus, after each step, ``step_detail`` seconds at ``step_interval`` [s]."""
    regular = np.arange(0.0, duration, interval)
    detail = np.arange(0.0, step_detail, step_interval)
    fine = (step_times[:, None] + detail[None, :]).ravel() if len(step_times) else np.zeros(0)
    grid = np.concatenate([regular, fine, [duration]])
    return np.unique(grid[(grid >= 0.0) & (grid <= duration)])


#: Table 3 motor constants and the averaged chopper's loop gain: the shipped motor models'
#: defaults, used for the initial equilibrium unless the scenario sets them.
MOTOR_DEFAULTS = {"k_e": 0.5, "N_c": 50.0, "R": 0.1, "K_current": 100.0, "T_d": 0.094}


def held_current(scenario: Scenario, reference: float) -> float:
    """Phase current [A] the drive holds for a reference current: K i_ref / (K + R) for the
    averaged chopper (its proportional loop's steady state), i_ref for the ideal-current model."""
    motor = scenario.roles.instance_of("torque") or "motor"
    if "IdealCurrent" in str(scenario.fmus.get(motor, "")):
        return reference
    values: dict[str, Any] = {**MOTOR_DEFAULTS, **scenario.parameters.get(motor, {})}  # as the scenario gives them
    return values["K_current"] * reference / (values["K_current"] + values["R"])


def loaded_lag(scenario: Scenario, reference: float, panel_angle: float, moment: float | None = None) -> float:
    """Elastic lag [rad] of the rotor behind its detent under the wind moment, held by ``reference`` A.

    Equilibrium of the panel: g C = M_ext with C = -k_e i sin(N_c delta) - T_d sin(4 N_c delta)
    ([paper], eqs. 9, 10, and the detent torque T_d of docs/physics.md) and g = s / (r cos^2 theta_p)
    ([paper], eq. 15). Without detent torque delta = asin(M_ext / (g k_e i)) / N_c; with it, the first
    x = N_c delta from the detent where k_e i sin x + T_d sin 4x reaches |M_ext| / g (the first
    equilibrium the wind pushes the rotor to, a stable one), found on a grid and refined by bisection.
    0 without wind; raises nothing when the moment exceeds what the drive holds (the lag is then
    capped at a quarter of an electrical period: the drive cannot hold and will slip). ``moment``:
    the external moment at the start [N.m] (default the constant ``wind.moment``).
    """
    moment = scenario.wind.moment if moment is None else moment
    if moment == 0.0 or reference == 0.0:
        return 0.0
    motor = scenario.roles.instance_of("torque") or "motor"
    values = {**MOTOR_DEFAULTS, **scenario.parameters.get(motor, {})}
    transmission = scenario.transmission
    g = transmission.lever_arm / (transmission.pinion_radius * np.cos(panel_angle) ** 2)
    holding = float(values["k_e"]) * held_current(scenario, reference)
    detent, teeth = float(values["T_d"]), float(values["N_c"])
    if detent == 0.0:
        return float(np.arcsin(np.clip(moment / (g * holding), -1.0, 1.0)) / teeth)

    def excess(x):  # held torque beyond the wind's, on the motor shaft [N.m]
        return holding * np.sin(x) + detent * np.sin(4 * x) - abs(moment) / g

    grid = np.linspace(0.0, np.pi / 2, 4097)
    reached = np.flatnonzero(excess(grid) >= 0.0)
    if len(reached) == 0:
        return float(np.sign(moment) * np.pi / 2 / teeth)
    low, high = grid[max(reached[0] - 1, 0)], grid[reached[0]]
    for _ in range(60):  # bisection: the bracket of 3.8e-4 rad down to rounding
        middle = 0.5 * (low + high)
        low, high = (middle, high) if excess(middle) < 0.0 else (low, middle)
    return float(np.sign(moment) * 0.5 * (low + high) / teeth)


def prepare_inputs(scenario: Scenario, should_stop: Callable[[], bool] | None = None) -> DriveInputs:
    """Compute the reference, the step schedule, the reference currents and the output grid.

    ``should_stop`` is asked while the steps are scheduled (the one loop that grows with the
    run); when it says so, :class:`~heliostep.drive.sequencer.PreparationStopped` is raised. The
    arrays built at once (reference, grid) are bounded by the run's estimate
    (:mod:`heliostep.run.estimate`) before this is called."""
    start, end = scenario.window_bounds()
    duration = (end - start).total_seconds()
    times = reference_times(duration)
    index = start + pd.to_timedelta(times, unit="s")
    panel = scenario_panel_angle(scenario, index)
    knots = wind_speed_knots(scenario, start, duration)
    plan = stow_plan(scenario, knots, times, panel, duration)
    if plan is not None:
        _refuse_a_loops_stow(scenario)  # before the schedule: bad input found early
        times, panel = plan.times, plan.panel_angle
    transmission = scenario.transmission
    rotor = rotor_angle_from_panel(
        panel, panel[0], transmission.pinion_radius, transmission.lever_arm, rotor_angle0=0.0
    )  # [paper], eq. 14, rotor at 0 at the start
    sequencer = scenario_sequencer(scenario)
    schedule = schedule_steps(
        reference_interpolant(times, commanded_rotor_angle(scenario, index, panel, rotor, plan is not None)),
        sequencer,
        trigger=scenario.sequencer.trigger,
        should_stop=should_stop,
    )

    indices = np.concatenate([[schedule.initial_index], schedule.indices])
    i_a_ref, i_b_ref = sequencer.reference_currents(indices)
    out = scenario.output
    grid = output_grid(duration, out.interval, schedule.times, out.step_detail, out.step_interval)
    signal = None
    if knots is not None and scenario.tracking.mode != "open_loop":
        signal = loop_wind_signal(scenario, knots, PchipInterpolator(times, panel, extrapolate=True), duration)
    elif knots is not None:
        signal = wind_moment_signal(scenario, knots, sequencer, schedule, float(panel[0]), duration)
    implied = implied_parameters(scenario, sequencer, schedule, (i_a_ref[0], i_b_ref[0]), float(panel[0]), signal)
    return DriveInputs(
        window_start=start,
        duration=duration,
        reference_times=times,
        panel_angle_ref=np.asarray(panel, dtype=float),
        rotor_angle_ref=np.asarray(rotor, dtype=float),
        sequencer=sequencer,
        schedule=schedule,
        current_a_ref=np.asarray(i_a_ref, dtype=float),
        current_b_ref=np.asarray(i_b_ref, dtype=float),
        wind_moment=scenario.wind.moment,
        output_times=grid,
        implied_parameters=implied,
        wind_signal=signal,
        stow_moves=() if plan is None else plan.moves,
        stowed_spans=() if plan is None else plan.stowed,
    )


def commanded_rotor_angle(scenario: Scenario, index: pd.DatetimeIndex, panel, rotor, stows: bool) -> np.ndarray:
    """The rotor angle [rad] the sequencer steps to: the reference's, or with ``faults.clock_offset`` the
    reference the controller's clock reads (the sun's position that many seconds later), through the
    same transmission from the true start."""
    offset = scenario.faults.clock_offset
    if offset == 0.0:
        return np.asarray(rotor, dtype=float)
    if stows:
        raise InputError(f"{scenario.source}: faults.clock_offset is not applied to stow moves; give no wind speed")
    shifted = scenario_panel_angle(scenario, index + pd.to_timedelta(offset, unit="s"))
    transmission = scenario.transmission
    return np.asarray(
        rotor_angle_from_panel(shifted, panel[0], transmission.pinion_radius, transmission.lever_arm, rotor_angle0=0.0),
        dtype=float,
    )


def implied_parameters(
    scenario: Scenario,
    sequencer: Sequencer,
    schedule: StepSchedule,
    currents: tuple[float, float],
    panel_start: float,
    signal: WindSignal | None,
) -> dict:
    """The parameters the scenario implies, by role: the run starts at the drive's holding
    equilibrium, the rotor at its loaded detent (the commanded position minus the elastic lag under
    the wind moment at the start), the panel where the transmission puts it; the motor model starts
    its currents at what its loop holds."""
    transmission = scenario.transmission
    rotor0 = float(sequencer.position(schedule.initial_index)) - loaded_lag(
        scenario,
        float(np.hypot(*currents)),
        panel_start,
        None if signal is None else float(signal.values[0]),
    )
    panel0 = float(np.arctan(np.tan(panel_start) + rotor0 * transmission.pinion_radius / transmission.lever_arm))
    return {
        "panel_angle_start": panel0,
        "rotor_angle_start": rotor0,
        "pinion_radius": transmission.pinion_radius,
        "lever_arm": transmission.lever_arm,
        "current_a_start": float(currents[0]),
        "current_b_start": float(currents[1]),
    }


def stow_plan(scenario: Scenario, knots: WindKnots | None, times, panel, duration: float) -> StowPlan | None:
    """The reference with the stow moves (:func:`heliostep.drive.stow.plan_stow`) when the wind's
    speed goes above ``wind.stow_speed`` in the window; None otherwise (the tracking reference stands)."""
    wind = scenario.wind
    if knots is None or wind.stow_speed is None:
        return None
    found = stowed_spans(knots.times, knots.speed, wind.stow_speed, wind.calm_time, duration)
    if not found:
        return None
    tracking = PchipInterpolator(times, panel, extrapolate=True)
    return plan_stow(times, tracking, found, np.radians(wind.stow_angle), np.radians(wind.slew_rate), duration)


def _refuse_a_loops_stow(scenario: Scenario) -> None:
    """InputError for a closed or hybrid loop in a window whose wind stows the panel (the stow moves are planned
    on the open-loop schedule)."""
    if scenario.tracking.mode != "open_loop":
        raise InputError(
            f"{scenario.source}: wind.stow_speed: the wind goes above {scenario.wind.stow_speed:g} m/s in the window "
            f"and stows the panel, planned on the open-loop schedule; with tracking.mode {scenario.tracking.mode} "
            "give wind.stow_speed: null, or a wind that stays below it"
        )


def loop_wind_signal(scenario: Scenario, knots: WindKnots, law, duration: float) -> WindSignal:
    """A closed or hybrid loop's ``m_ext`` signal: the wind's on the tracking law's panel angle ``law`` [rad of
    s], where the loop keeps the panel (its commanded index takes up the steps that slip, so the commanded
    angle open loop's moment follows can leave the panel for good)."""
    return moment_signal(scenario, knots, np.zeros(0), law, duration)


def wind_moment_signal(
    scenario: Scenario,
    knots: WindKnots,
    sequencer: Sequencer,
    schedule: StepSchedule,
    panel_start: float,
    duration: float,
) -> WindSignal:
    """The wind's ``m_ext`` signal on the commanded panel angle (:func:`heliostep.drive.wind_load.moment_signal`):
    the commanded rotor position through the transmission, 0 at ``panel_start`` [rad]."""
    transmission = scenario.transmission

    def commanded(t):
        rotor_cmd = sequencer.position(schedule.index_at(np.asarray(t, dtype=float)))
        return commanded_panel_angle(rotor_cmd, panel_start, transmission.pinion_radius, transmission.lever_arm)

    return moment_signal(scenario, knots, schedule.times, commanded, duration)


def scenario_panel_angle(scenario: Scenario, index: pd.DatetimeIndex) -> np.ndarray:
    """The scenario's mirror's reference panel angle [rad] at the instants *index*."""
    mirror = scenario.mirror
    return panel_angle_reference(
        index,
        scenario.site.to_site(),
        scenario.plant.to_plant(),
        mirror.mirror_distance,
        axis=mirror.axis,
        stow=mirror.stow,
        stow_angle=np.radians(mirror.stow_angle),
    ).to_numpy()


def scenario_sequencer(scenario: Scenario) -> Sequencer:
    """The scenario's sequencer (its step angle in [rad])."""
    return Sequencer(
        mode=scenario.sequencer.mode,
        current=scenario.sequencer.current,
        step_angle=np.radians(scenario.sequencer.step_angle),
        microsteps=scenario.sequencer.microsteps,
        idle_current_fraction=scenario.sequencer.idle_current_fraction,
        idle_delay=scenario.sequencer.idle_delay,
    )
