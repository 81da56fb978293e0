"""A closed or hybrid tracking loop in a run: the controller of the scenario, and the steps it decides.

The controller (:class:`~heliostep.drive.closed_loop.TrackingLoop`) decides the steps while the system is
simulated, once: the solver-step figures follow its steps as they are decided, the output rows wait until
the run ends and are then assembled on the steps decided (:func:`decided_inputs`), so every figure, trace
column and plot of an open-loop run follows unchanged.

Details: docs/tracking.md.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pandas as pd

from heliostep.cosim.controller import ScheduledInput
from heliostep.drive.closed_loop import STEP_INDEX, LoopLaw, SensorView, TrackingLoop, realized_schedule
from heliostep.drive.inputs import DriveInputs, output_grid
from heliostep.errors import InputError
from heliostep.scenario import Scenario
from heliostep.scenario.sun_sensors import sun_sensor
from heliostep.scenario.tracking import SENSOR_INSTANCE
from heliostep.solar import clear_sky_irradiance, cloud_fraction, panel_angle_from_rotor, rotor_angle_from_panel

__all__ = ["decided_inputs", "loop_inputs", "sensor_parameters", "tracking_loop"]

#: Standard deviations of a reading's noise the default dead band spans: a still panel steps on noise
#: alone in 0.3 % of its readings (a normal distribution's two-sided 3-sigma tail).
DEAD_BAND_SIGMAS = 3.0


def sensor_parameters(scenario: Scenario) -> dict[str, float]:
    """The sun sensor FMU's parameters: its preset's, the mounting offset of ``faults``, then the user's."""
    preset = sun_sensor(scenario.tracking.sensor)
    values: dict[str, float] = {**preset.parameters, "offset": float(np.radians(scenario.faults.mounting_offset))}
    return {**values, **scenario.parameters.get(SENSOR_INSTANCE, {})}  # type: ignore[dict-item]


class _Transmission:
    """Step index <-> commanded panel angle through the rack and pinion ([paper], eq. 14,
    :mod:`heliostep.solar.transmission`): the rotor at 0 at the reference's first panel angle [rad]."""

    def __init__(self, inputs: DriveInputs, pinion_radius: float, lever_arm: float):
        self.sequencer, self.panel0 = inputs.sequencer, float(inputs.panel_angle_ref[0])
        self.pinion_radius, self.lever_arm = pinion_radius, lever_arm

    def panel_of_index(self, index: float) -> float:
        rotor = float(self.sequencer.position(index))
        return float(panel_angle_from_rotor(rotor, self.panel0, self.pinion_radius, self.lever_arm))

    def index_of_panel(self, panel: float) -> float:
        rotor = float(rotor_angle_from_panel(panel, self.panel0, self.pinion_radius, self.lever_arm))
        return (rotor - self.sequencer.offset) / self.sequencer.increment


def sensor_views(
    scenario: Scenario, inputs: DriveInputs, sample_times: np.ndarray, noise_std: float, weather=None
) -> np.ndarray:
    """What the sensor is given at the start and at each sample (rows): the ideal panel angle [rad], the DNI
    (cut by the scenario's clouds) and the diffuse horizontal irradiance [W/m2] of the weather file (already
    read) or the clear sky, and a reading's noise [-] (normal, ``noise_std``, seeded by ``tracking.seed``)."""
    times = np.concatenate([[0.0], sample_times])
    grid = np.asarray(inputs.reference_times, dtype=float)
    instants = inputs.window_start + pd.to_timedelta(grid, unit="s")
    if weather is not None:
        try:
            sky = pd.DataFrame({"dni": weather.at(instants), "dhi": weather.diffuse_at(instants)})
        except InputError as exc:
            raise InputError(f"{scenario.source}: optics.{exc}") from None
    else:
        sky = clear_sky_irradiance(instants, scenario.site.to_site())
    clouds = cloud_fraction(times, scenario.tracking.cloud_spans)
    dni = np.interp(times, grid, sky["dni"].to_numpy(dtype=float)) * clouds
    dhi = np.interp(times, grid, sky["dhi"].to_numpy(dtype=float))
    noise = np.random.default_rng(scenario.tracking.seed).normal(0.0, noise_std, len(times)) if noise_std else 0 * times
    noise[0] = 0.0
    return np.column_stack([inputs.panel_reference()(times), dni, dhi, noise])


def tracking_loop(scenario: Scenario, inputs: DriveInputs, roles: dict[str, str], weather=None) -> TrackingLoop:
    """The scenario's controller (``tracking`` not ``open_loop``), deciding its steps; ``weather``: the
    scenario's weather file already read (its DNI and diffuse reach the sensor), None: the clear sky."""
    tracking = scenario.tracking
    preset = sun_sensor(tracking.sensor)
    values = sensor_parameters(scenario)
    k_ray, fov = float(values["k_ray"]), float(values["fov"])
    noise = preset.noise_std if tracking.noise_std is None else float(np.radians(tracking.noise_std))  # [rad]
    dead_band = DEAD_BAND_SIGMAS * noise / k_ray  # [rad] of panel angle
    if tracking.dead_band is not None:
        dead_band = float(np.radians(tracking.dead_band))
    sequencer = inputs.sequencer
    increments = sequencer.step_angle / sequencer.increment  # sequencer increments per full step
    law = LoopLaw(
        mode=tracking.mode,
        sample_period=tracking.sample_period,
        dead_band=float(dead_band),
        step_rate=tracking.step_rate * increments,
        latency=tracking.latency,
        move=None if tracking.move is None else float(np.radians(tracking.move)),
    )
    transmission = _Transmission(inputs, scenario.transmission.pinion_radius, scenario.transmission.lever_arm)
    count = int(np.floor(inputs.duration / tracking.sample_period + 1e-9))
    sample_times = tracking.sample_period * np.arange(1, count + 1)
    stuck = scenario.faults.stuck
    if stuck is not None and stuck[1] < inputs.duration:  # the driver taken up at the span's end: a sample
        sample_times = np.union1d(sample_times, [stuck[1]])
    return TrackingLoop(
        law,
        sequencer,
        SensorView(k_ray, fov),
        sensor_instance=SENSOR_INSTANCE,
        initial_index=inputs.schedule.initial_index,
        panel_of_index=transmission.panel_of_index,
        index_of_panel=transmission.index_of_panel,
        sample_times=sample_times,
        views=sensor_views(scenario, inputs, sample_times, noise / np.tan(fov), weather),  # the signal's, near balance
        open_loop=inputs.schedule,
        stuck=stuck,
        inputs=_commands(sequencer, inputs.schedule.initial_index, roles),
        step_detail=np.arange(0.0, scenario.output.step_detail, scenario.output.step_interval),
    )


def _commands(sequencer, initial_index: int, roles: dict[str, str]) -> tuple[ScheduledInput, ...]:
    """The master inputs the controller appends its steps to: the phase currents' references (into the
    FMU inputs of their roles) and the step index (traced only), each at its value at the start."""
    i_a, i_b = sequencer.reference_currents(initial_index)
    return (
        ScheduledInput("i_a_ref", roles["current_a_ref"], float(i_a)),
        ScheduledInput("i_b_ref", roles["current_b_ref"], float(i_b)),
        ScheduledInput(STEP_INDEX, "", float(initial_index)),
    )


def loop_inputs(inputs: DriveInputs, loop: TrackingLoop, scenario: Scenario) -> DriveInputs:
    """The run's inputs while its controller decides the steps: its schedule (growing while simulating) and
    the output grid of the steps decided before the start (the rest join the grid as they are decided)."""
    out = scenario.output
    grid = output_grid(inputs.duration, out.interval, loop.schedule.times, out.step_detail, out.step_interval)
    return dataclasses.replace(inputs, schedule=loop.schedule, output_times=grid)


def decided_inputs(inputs: DriveInputs, trace: pd.DataFrame, scenario: Scenario) -> DriveInputs:
    """The run's inputs on the steps a controller decided, read from the ``trace`` of the simulation it
    decided them in (its ``time`` and ``step_index`` columns; a failed or stopped one gives the steps up to
    there): the schedule, the phase currents and the output grid of those steps."""
    schedule = realized_schedule(trace["time"].to_numpy(), trace[STEP_INDEX].to_numpy(), inputs.schedule.initial_index)
    indices = np.concatenate([[schedule.initial_index], schedule.indices])
    i_a, i_b = inputs.sequencer.reference_currents(indices)
    out = scenario.output
    grid = output_grid(inputs.duration, out.interval, schedule.times, out.step_detail, out.step_interval)
    decided = dataclasses.replace(
        inputs,
        schedule=schedule,
        current_a_ref=np.asarray(i_a, dtype=float),
        current_b_ref=np.asarray(i_b, dtype=float),
        output_times=grid,
    )
    return decided
