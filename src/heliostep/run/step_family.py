"""Step families: a case's figures composed from the single-step transients of its own drive.

An open-loop day is some thousands of steps from a settled detent separated by rests in which nothing
moves. Each step's transient is decided by the phase transition, its direction and the panel's angle
(the transmission's ratio, the inertia and load the rotor sees); the drive's other conditions are
the scenario's and constant over the day. A family co-simulates those transients once, through the
master and FMUs a run uses (:func:`build_family`), and :func:`compose_case` reads a case's figures off
it along the case's step schedule. A case whose steps leave what a family assumes is not composed
(:attr:`ComposedCase.fallback` says why): the caller runs it in full. Method and limits: docs/sweep.md.
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import json
import time as clock
from collections.abc import Callable, Mapping

import numpy as np
import pandas as pd
from scipy.interpolate import CubicSpline

from heliostep.cosim import SimulationError
from heliostep.drive.inputs import DriveInputs, implied_parameters, prepare_inputs
from heliostep.drive.sequencer import PATTERNS, StepSchedule
from heliostep.drive.wind_load import commanded_panel_angle
from heliostep.results.figures.solution import SolutionRecorder
from heliostep.results.figures.steps import SETTLING_BAND, rest_detent
from heliostep.results.figures.tradeoffs import energy_per_day
from heliostep.results.light.on_tube import LightIntegrals
from heliostep.results.trace.frame import drive_metadata
from heliostep.run.bindings import parameters
from heliostep.run.runner import _prepare, _system
from heliostep.run.step_settling import LOBES, lobes, settling_figures
from heliostep.scenario import Scenario, validate_scenario

__all__ = [
    "ComposedCase",
    "StepFamily",
    "build_family",
    "compose_case",
    "family_key",
    "not_composable",
]

#: The family's panel angles [deg]: a linear Fresnel mirror's span while the sun is up, every 5 deg.
FAMILY_ANGLES_DEG = np.linspace(-60.0, 60.0, 25)
#: A transient: held this long [s] at its detent, then stepped, then watched until the window's end [s]
#: (the ring of a step dies out within a tenth of a second: docs/sweep.md).
STEP_AT, WINDOW = 0.02, 1.0
#: The light on the tube composed at rows this many seconds apart from the window's start [s].
LIGHT_EVERY = 60.0
#: The light figures a composed case carries (:class:`~heliostep.results.light.on_tube.LightIntegrals`'s).
LIGHT_FIGURES = ("light_energy_J", "light_energy_ideal_J", "light_lost_J")
#: A reversal's start that sits off the family's settled detent by more than this share of a step falls back.
REVERSAL_OFFSET = 0.01
#: A step whose panel still moves this long after it [s] creeps toward its rest slower than a family's window
#: shows (its rest at the window's end is not the one the next step starts from): its case falls back.
CREEP = 0.5 * (WINDOW - STEP_AT)
_FIELDS = tuple(
    "peak_torque peak_current energy overshoot overshoot_time rest slip missed lost failed ring lag".split()
)


@dataclasses.dataclass(frozen=True)
class StepFamily:
    """A drive's single-step transients: each field per (panel angle, direction -1/+1, phase transition).

    Attributes
    ----------
    key : str
        :func:`family_key` of the cases it serves.
    angles : ndarray
        Panel angles [rad] at which the steps start.
    table : dict of ndarray
        Per field, shape (angles, 2, cycle): ``peak_torque`` [N.m], ``peak_current`` [A], ``energy`` above
        holding [J], ``overshoot`` past the new detent [steps] and its time after the step [s], ``rest``
        off the detent at the end [rad], ``slip`` whole steps lost (signed), ``missed``, ``lost``, ``failed``
        (the drive ran away), ``ring`` (last time after the step farther than 5 % of a step from rest [s]),
        ``lag`` the rotor's lag behind its detent held before the step [settling bands: SETTLING_BAND of a
        step increment].
    lobes : ndarray
        The swings of each step's ring, shape (angles, 2, cycle, LOBES, 4)
        (:func:`~heliostep.run.step_settling.lobes`).
    holding_power : ndarray
        Electrical power holding each phase of the cycle [W].
    cpu_s : float
        CPU time the family took [s].
    """

    key: str
    angles: np.ndarray
    table: dict
    lobes: np.ndarray
    holding_power: np.ndarray
    cpu_s: float

    @property
    def cycle(self) -> int:
        """Step indices per electrical cycle (the phase transitions a family distinguishes)."""
        return len(self.holding_power)

    def at(self, name: str, angle: np.ndarray, direction: np.ndarray, phase: np.ndarray) -> np.ndarray:
        """Field ``name`` at each step's panel angle [rad], direction and phase: a cubic spline in the angle
        (a peak and an energy are smooth in it); an outcome (missed, lost, failed) the worse of the two
        family angles around the step's; the whole steps slipped, the nearest angle's."""
        table = self.table[name]
        if name == "slip":
            values = table[np.rint(np.interp(angle, self.angles, np.arange(len(self.angles)))).astype(int)]
        elif name in ("missed", "lost", "failed"):
            right = np.clip(np.searchsorted(self.angles, angle), 1, len(self.angles) - 1)
            values = np.maximum(table[right - 1], table[right])
        else:
            values = self._splines[name](angle)
        return values[np.arange(len(angle)), (direction > 0).astype(int), phase]

    @functools.cached_property
    def _splines(self) -> dict[str, CubicSpline]:
        """The smooth fields' cubic splines in the panel angle, made once (a transient that failed is nan:
        the case falls back, and its neighbours' largest stands in)."""
        splines = {}
        for name, table in self.table.items():
            if name not in ("slip", "missed", "lost", "failed"):
                table = np.where(np.isfinite(table), table, np.nanmax(table, initial=0.0))
                splines[name] = CubicSpline(self.angles, table, axis=0)
        return splines


@dataclasses.dataclass(frozen=True)
class ComposedCase:
    """A case's figures composed from its family (peak torque and phase current, electrical energy and the
    drive's energy per day, maximum tracking error, settling times, light on the tube and with ideal
    tracking, steps missed, lost, commanded and executed, the duration), or ``fallback``: why the case must
    be run in full."""

    figures: dict
    fallback: str | None = None


def not_composable(scenario: Scenario) -> str | None:
    """Why ``scenario``'s steps cannot come from a family (its drive's conditions change over the day, or
    its steps are decided while simulating), or None."""
    wind, sequencer = scenario.wind, scenario.sequencer
    if scenario.tracking.mode != "open_loop":
        return f"tracking.mode {scenario.tracking.mode} (its steps are decided while simulating)"
    if scenario.faults.model_dump(exclude_defaults=True):
        return "faults (a drive that is not the family's for part of the day)"
    if wind.speed is not None or wind.weather_file is not None or wind.profile is not None:
        return "wind by its speed (a load that changes over the day)"
    if sequencer.idle_current_fraction < 1.0:
        return "sequencer.idle_current_fraction below 1 (steps that start from the idle current)"
    return None


def family_key(scenario: Scenario, fmu_digests: Mapping[str, str] | None = None) -> str:
    """Which cases share a family: the scenario's drive (FMUs, parameters, connections, transmission,
    sequencer, wind moment, solver, the mirror's axis), without what only moves the sun and the light.
    ``fmu_digests`` (instance -> the FMU file's SHA-256) stand for the FMUs' paths where given (a sweep's
    workers unpack the same FMU to folders of their own)."""
    data = scenario.resolved_dict()
    if fmu_digests is not None:
        data["fmus"] = dict(fmu_digests)
    for section in ("name", "description", "site", "window", "plant", "optics", "output", "budget"):
        data.pop(section, None)
    data["mirror"] = {key: data["mirror"][key] for key in ("axis", "stow", "stow_angle")}
    return hashlib.sha256(json.dumps(data, sort_keys=True, default=str).encode()).hexdigest()[:16]


def build_family(
    scenario: Scenario, should_stop: Callable[[], bool] | None = None, fmu_digests: Mapping[str, str] | None = None
) -> StepFamily:
    """The step family of ``scenario``'s drive: one step from the loaded detent at each of
    :data:`FAMILY_ANGLES_DEG`, both directions, each phase transition, and the holding without a step,
    each co-simulated over :data:`WINDOW` through the master a run builds (its FMUs, roles, parameters
    and solver)."""
    started = clock.process_time()
    data = scenario.resolved_dict()
    data["window"] = {"date": data["window"]["date"], "start": "12:00", "duration": WINDOW}
    short = validate_scenario(data, source=scenario.source, folder=scenario.folder)
    prepared = _prepare(short, None, clock.perf_counter(), keep_trace=False)
    cycle = _cycle(prepared.inputs.sequencer)
    angles = np.radians(FAMILY_ANGLES_DEG)
    table = {name: np.zeros((len(angles), 2, cycle)) for name in _FIELDS}
    swings = np.zeros((len(angles), 2, cycle, LOBES, 4))
    middle = float(angles[len(angles) // 2])
    holding = np.array([_transient(prepared, middle, p, 0)["energy"] / WINDOW for p in range(cycle)])
    for i, angle in enumerate(angles):
        if should_stop is not None and should_stop():
            raise InterruptedError("stopped while building a step family")
        for d, direction in enumerate((-1, 1)):
            for p in range(cycle):
                figures = _transient(prepared, float(angle), p, direction)
                figures["energy"] -= holding[p] * WINDOW
                for name in _FIELDS:
                    table[name][i, d, p] = figures[name]
                swings[i, d, p] = figures["lobes"]
    key = family_key(scenario, fmu_digests)
    return StepFamily(key, angles, table, swings, holding, clock.process_time() - started)


class _Watch:
    """The master's monitor for one transient: the run's solution figures, and the panel and the rotor
    from the step on."""

    def __init__(self, recorder: SolutionRecorder, panel: int, rotor: int):
        self.recorder, self.columns, self.rows = recorder, [0, panel, rotor], [np.zeros((0, 3))]

    def __call__(self, rows: np.ndarray) -> None:
        self.recorder(rows)
        rows = np.atleast_2d(rows)
        self.rows.append(rows[rows[:, 0] >= STEP_AT][:, self.columns].copy())

    def swings(self, sequencer, commanded: float) -> np.ndarray:
        """The step's ring as :func:`~heliostep.run.step_settling.lobes` keeps it: the rotor about its rest
        as the run's step judge takes it (``commanded`` [rad] less the lag held at the first row)."""
        time, _, rotor = np.concatenate(self.rows).T
        lag = self.recorder.steps.lag
        if not len(time) or lag is None:
            return np.zeros((LOBES, 4))
        rest = rest_detent(commanded, lag, rotor[-1], sequencer)
        return lobes(time, (rotor - rest) / (SETTLING_BAND * sequencer.increment), STEP_AT)

    def motion(self, target: float, direction: int, step: float, cycle: int) -> dict:
        """The swing past the new detent ``target`` [rad] (in panel steps ``step`` [rad]) and its time after
        the step; where the panel rests at the end: whole electrical cycles off (``slip``, steps lost) and
        the rest [rad]; the ring [s]."""
        time, panel, _ = np.concatenate(self.rows).T
        time, panel = time[time > STEP_AT], panel[time > STEP_AT]
        if not len(time):
            return {"overshoot": 0.0, "overshoot_time": 0.0, "rest": 0.0, "slip": 0.0, "ring": 0.0}
        past = direction * (panel - target)
        k = int(np.argmax(past))
        off = np.abs(panel - panel[-1]) > 0.05 * step
        slip = cycle * float(np.rint((panel[-1] - target) / step / cycle))
        return {
            "overshoot": float(past[k]) / step,
            "overshoot_time": float(time[k]) - STEP_AT,
            "rest": float(panel[-1]) - target - slip * step,
            "slip": slip,
            "ring": float(time[off].max(initial=STEP_AT)) - STEP_AT,
        }


def _transient(prepared, angle: float, index: int, direction: int) -> dict:
    """One step (``direction`` 0: none) from index ``index`` held with the panel at ``angle`` [rad],
    co-simulated over :data:`WINDOW` as ``prepared`` (a run's set-up) would: its figures."""
    scenario, sequencer = prepared.scenario, prepared.inputs.sequencer
    r, s = scenario.transmission.pinion_radius, scenario.transmission.lever_arm
    steps = [index + direction] if direction else []
    schedule = StepSchedule(np.array([STEP_AT] if direction else [], dtype=float), np.array(steps, dtype=int), index)
    current_a, current_b = sequencer.reference_currents(np.array([index, *steps]))
    start = float(commanded_panel_angle(-sequencer.position(index), angle, r, s))  # the panel at rotor 0
    implied = implied_parameters(scenario, sequencer, schedule, (current_a[0], current_b[0]), start, None)
    end = index + direction
    target = float(commanded_panel_angle(sequencer.position(end), start, r, s))
    ends = np.array([0.0, WINDOW])
    inputs = dataclasses.replace(
        prepared.inputs,
        duration=WINDOW,
        reference_times=ends,
        output_times=ends,
        schedule=schedule,
        implied_parameters=implied,
        panel_angle_ref=np.full(2, target),
        rotor_angle_ref=np.full(2, float(sequencer.position(end))),
        current_a_ref=current_a,
        current_b_ref=current_b,
    )
    values = parameters(scenario, inputs, prepared.roles, prepared.infos)
    system = _system(scenario, prepared.infos, inputs, values, prepared.roles, None)
    columns = ["time", *[item.name for item in system.inputs]]
    columns += [f"{name}.{output}" for name, info in system.fmus.items() for output in info.traced_outputs]
    recorder = SolutionRecorder(columns, prepared.roles, sequencer, schedule, None)
    watch = _Watch(recorder, columns.index(prepared.roles["panel_angle"]), columns.index(prepared.roles["rotor_angle"]))
    try:
        system.simulate(0.0, WINDOW, ends, prepared.solver, monitor=watch)
    except SimulationError:  # the drive runs away: an outcome a family cannot compose (a case falls back)
        failed = {"slip": 0.0, "missed": 1.0, "lost": 1.0, "failed": 1.0, "lobes": np.zeros((LOBES, 4))}
        return {**dict.fromkeys(_FIELDS, np.nan), **failed}
    figures = recorder.figures()
    step = abs(target - angle) if direction else 1.0  # the panel's step between the two detents
    return {
        "peak_torque": figures["peak_torque_Nm"],
        "peak_current": figures["peak_phase_current_A"],
        "energy": figures["electrical_energy_J"],
        **watch.motion(target, direction or 1, step, _cycle(sequencer)),
        "missed": figures["missed_steps"] if direction else 0,
        "lost": figures["steps_lost"],
        "lag": watch.recorder.steps.lag / (SETTLING_BAND * sequencer.increment),
        "lobes": watch.swings(sequencer, float(sequencer.position(end))) if direction else np.zeros((LOBES, 4)),
        "failed": 0.0,
    }


def _cycle(sequencer) -> int:
    """Step indices per electrical cycle of ``sequencer``'s currents."""
    return 4 * sequencer.microsteps if sequencer.microsteps > 1 else len(PATTERNS[sequencer.mode])


def compose_case(
    scenario: Scenario,
    family: StepFamily,
    inputs: DriveInputs | None = None,
    fmu_digests: Mapping[str, str] | None = None,
) -> ComposedCase:
    """``scenario``'s figures read off ``family`` along its step schedule (``inputs``: its
    :func:`~heliostep.drive.inputs.prepare_inputs`, computed when not given), or why it falls back.

    Peaks: the largest of its steps' (each a spline in the panel angle). Electrical energy: holding
    power times the time at each phase, plus each step's energy above holding. Tracking error: the
    reference minus the panel at rest (its detent, a load's lag), at every interval's ends and at each
    step's swing past its target. Settling: each step's from the swings of its ring
    (:mod:`heliostep.run.step_settling`). Light on the tube: :class:`~heliostep.results.light.on_tube.LightIntegrals`
    on that panel angle. Steps missed and lost: the family's outcomes.
    """
    if family.key != family_key(scenario, fmu_digests):
        raise ValueError("the family is another drive's (family_key differs)")
    inputs = prepare_inputs(scenario) if inputs is None else inputs
    schedule = inputs.schedule
    held = np.concatenate([[schedule.initial_index], schedule.indices])
    direction, phase = np.diff(held), np.mod(held[:-1], family.cycle)
    commanded = _panel_at(inputs, scenario, held)
    at = {name: family.at(name, commanded[:-1], direction, phase) for name in _FIELDS}
    fallback = _fallback(family, commanded, inputs, at, (direction, phase))
    if fallback is not None:
        return ComposedCase({}, fallback)
    bounds = np.concatenate([[0.0], schedule.times, [inputs.duration]])
    holding = float(np.sum(family.holding_power[np.mod(held, family.cycle)] * np.diff(bounds)))
    panel = commanded + np.concatenate([at["rest"][:1], at["rest"]])  # at rest, a load's lag off the detent
    missed = int(np.rint(at["missed"]).sum())
    figures = {
        "peak_torque_Nm": float(at["peak_torque"].max(initial=0.0)),
        "peak_phase_current_A": float(at["peak_current"].max(initial=0.0)),
        "electrical_energy_J": holding + float(at["energy"].sum()),
        "max_tracking_error_deg": _max_tracking_error(inputs, commanded, panel, at, direction),
        **settling_figures(
            family.lobes, family.angles, commanded[:-1], (direction, phase), at["lag"], np.diff(bounds)[1:]
        ),
        **_light(scenario, inputs, panel),
        "missed_steps": missed,
        "steps_lost": int(np.rint(at["lost"]).sum()),
        "steps_commanded": len(schedule),
        "steps_executed": len(schedule) - missed,
        "duration_s": inputs.duration,
        "stowed_time_s": 0.0,  # a family's case has no stow move (no wind speed)
        "light_lost_stowed_J": 0.0,
    }
    figures.update(energy_per_day(figures, scenario))
    return ComposedCase(figures)


def _panel_at(inputs: DriveInputs, scenario: Scenario, held: np.ndarray) -> np.ndarray:
    """The panel angle [rad] at the detent of each step index ``held``: the transmission from the start."""
    transmission = scenario.transmission
    rotor = inputs.sequencer.position(held)
    return commanded_panel_angle(rotor, inputs.panel_angle_ref[0], transmission.pinion_radius, transmission.lever_arm)


def _fallback(family: StepFamily, commanded: np.ndarray, inputs: DriveInputs, at: dict, steps) -> str | None:
    """Why a case's steps leave what the family assumes, or None: no step at all, a stow move, a step
    outside its angles, a step before the previous one's ring has died out, a transient that ran away or
    lost steps, or still moves after :data:`CREEP`, a reversal that starts off the settled detent (friction
    holding the panel where the other direction left it) by over :data:`REVERSAL_OFFSET` of a step.
    ``commanded``: the panel at each detent [rad]; ``steps``: each step's (direction, phase)."""
    angle, (direction, phase) = commanded[:-1], steps
    if not len(angle):
        return "no step in the window"
    if inputs.stow_moves:
        return "stow moves (steps faster than a step's ring decays)"
    if angle.min() < family.angles[0] or angle.max() > family.angles[-1]:
        span = f"{np.degrees(angle.min()):.1f} .. {np.degrees(angle.max()):.1f} deg"
        return f"steps outside the family's panel angles ({span})"
    if not _full_currents(inputs):
        return "reference currents other than the sequencer's full ones of the index held"
    early = int(np.sum(np.diff(inputs.schedule.times) < at["ring"][:-1]))  # each step's ring against its rest
    if early:
        return f"{early} steps before the previous step's ring died out"
    if np.any(at["failed"] > 0) or np.any(at["lost"] > 0) or np.any(at["slip"] != 0):
        return "steps lost, or a drive that runs away, in the family's transients"
    if np.any(at["ring"] > CREEP):  # after the two above: a transient that failed has no ring
        return f"steps still moving {CREEP:.2g} s after they are made (a creep slower than the family's window)"
    other = family.at("rest", angle, -direction, phase)
    offset = np.abs(at["rest"] - other) / np.abs(np.diff(commanded)) * (np.diff(direction, prepend=direction[0]) != 0)
    if np.any(offset > REVERSAL_OFFSET):
        count = int(np.sum(offset > REVERSAL_OFFSET))
        return f"{count} reversals start off the detent by up to {offset.max():.1%} of a step"
    return None


def _full_currents(inputs: DriveInputs) -> bool:
    """Whether the reference currents are, before the first step and from each step on, the sequencer's
    full currents of the index held (the family's transients start from them and hold them)."""
    schedule = inputs.schedule
    held = np.concatenate([[schedule.initial_index], schedule.indices])
    if len(inputs.current_a_ref) != len(held):
        return False
    current_a, current_b = inputs.sequencer.reference_currents(held)
    return bool(np.array_equal(current_a, inputs.current_a_ref) and np.array_equal(current_b, inputs.current_b_ref))


def _max_tracking_error(inputs: DriveInputs, commanded, panel, at: dict, direction) -> float:
    """The largest |panel - reference| [deg]: at each interval's ends (the panel at rest), at each step's
    swing past its target, at the reference's knots."""
    times, reference = inputs.schedule.times, inputs.panel_reference()
    bounds = np.concatenate([[0.0], times, [inputs.duration]])
    swing = direction * at["overshoot"] * np.abs(np.diff(commanded))
    errors = np.concatenate(
        [
            panel - reference(bounds[:-1]),
            panel - reference(bounds[1:]),
            commanded[1:] + swing - reference(times + at["overshoot_time"]),
            panel[np.searchsorted(times, inputs.reference_times, side="right")] - inputs.panel_angle_ref,
        ]
    )
    return float(np.degrees(np.abs(errors).max()))


def _light(scenario: Scenario, inputs: DriveInputs, panel: np.ndarray) -> dict:
    """:data:`LIGHT_FIGURES` as a run's figures give them (no first-order terms) on the panel at rest, at
    rows every :data:`LIGHT_EVERY` seconds from the window's start and at its end, the sun grid at the rows."""
    roles = scenario.resolved_roles()
    grid = np.append(np.arange(0.0, inputs.duration, LIGHT_EVERY), inputs.duration)
    held = np.searchsorted(inputs.schedule.times, grid, side="right")
    trace = pd.DataFrame(
        {"time": grid, "panel_angle_ref": inputs.panel_reference()(grid), roles["panel_angle"]: panel[held]}
    )
    drive = {**drive_metadata(inputs), "step_times": []}  # no solver steps to correct the rows with
    metadata = {"window_start": inputs.window_start.isoformat(), "roles": roles, "drive": drive}
    light = LightIntegrals(metadata, scenario, first_order=False, wanted=LIGHT_FIGURES, sun_grid_s=LIGHT_EVERY)
    light(trace)
    figures = light.figures()
    return {name: float(figures[name]) for name in LIGHT_FIGURES}
