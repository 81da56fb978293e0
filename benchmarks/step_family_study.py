"""Step families, a feasibility study: year-field cases composed from single-step transients, against full runs.

    .venv/bin/python benchmarks/step_family_study.py [--days 80 172 355] [--mirrors 0 9] [--angles 13] [--window 1]
        [--light-every 10] [--set KEY=VALUE ...] [--scenario FILE]

Runs cases of ``scenarios/sweeps/year-field.yaml`` (``--days`` x the secondary drives of ``--mirrors``, and each
day's shared primary; ``--set`` added to every case, e.g. a weak drive ``--set sequencer.current=2 --set
wind.moment=85``; or one ``--scenario`` file, e.g. ``scenarios/jan21-weak-motor.yaml``) in full (``run_scenario``,
no trace kept, in this process). For each kind of drive it co-simulates a step family of its FMUs through the same
master (:class:`heliostep.cosim.CoSimulation` as ``run_scenario`` builds it): one step from the settled (loaded)
detent over ``--window`` seconds at ``--angles`` panel angles over the cases' range x the four phase transitions x
both directions, and the holding without a step. From the family and each case's step schedule (``prepare_inputs``,
no simulation) it composes the case's figures: peak torque and phase current (the largest per-step peak, a cubic
spline in the panel angle), electrical energy (holding power x time + each step's transient energy), maximum
tracking error (reference minus the panel at rest: its detent, the whole steps lost so far and a load's lag, the
step's swing past its target added after it), light on the tube (``LightIntegrals`` on that angle, on the case's
output grid every ``--light-every`` seconds), steps missed and lost (the family's outcomes).

Prints per family its CPU seconds and each field's range and spread over the phase transitions; per case the CPU
seconds of the full run and of the composition (schedule, figures, light), the shortest step interval, where the
case leaves what the family assumes (fall back), and per figure: full, composed, deviation (relative; missed and
lost: the difference), the issue's tolerance, whether it holds, what the composed figure comes from; then the
largest deviations and the year-field's cost extrapolated from the cases' mean CPU (line ``year-field: ...``).
"""

from __future__ import annotations

import argparse
import dataclasses
import time
from pathlib import Path

import numpy as np
import pandas as pd

ROOT = Path(__file__).resolve().parents[1]
SWEEP = ROOT / "scenarios" / "sweeps" / "year-field.yaml"
STEP_AT = 0.02  # [s] the family's step, after this much holding
PHASES = 4  # one-phase-on: the four phase transitions of a full-step cycle
#: The issue's tolerances: relative deviation (0 = exact).
TOLERANCES = dict(peak_torque_Nm=5e-3, peak_phase_current_A=5e-3, electrical_energy_J=1e-3)
TOLERANCES |= dict(max_tracking_error_deg=1e-2, light_energy_J=1e-3, missed_steps=0.0, steps_lost=0.0)
PEAKS = {"peak_torque_Nm": "peak_torque", "peak_phase_current_A": "peak_current"}  # figure -> family field
FIELDS = tuple("peak_torque peak_current energy overshoot overshoot_time rest slip missed lost failed ring".split())


def full_run(scenario) -> tuple[dict | None, float]:
    """(summary, CPU seconds) of the case run in full, as a sweep's worker runs it but in this process; the
    summary None when the run fails (as a sweep's case row would say)."""
    from heliostep.run import RunFailed, RunOptions, run_scenario

    started = time.process_time()
    try:
        summary = run_scenario(scenario, RunOptions(keep_trace=False, supervise=False, light_first_order=False)).summary
    except RunFailed as exc:
        print(f"full run failed: {str(exc)[:160]}")
        summary = None
    return summary, time.process_time() - started


class _Watch:
    """The master's monitor for one transient: the run's figures, and the panel's rows after the step."""

    def __init__(self, recorder, panel: int):
        self.recorder, self.panel, self.rows = recorder, panel, [np.zeros((0, 2))]

    def __call__(self, rows: np.ndarray) -> None:
        self.recorder(rows)
        rows = np.atleast_2d(rows)
        self.rows.append(rows[rows[:, 0] > STEP_AT][:, [0, self.panel]].copy())

    def motion(self, target: float, direction: int, step: float) -> dict:
        """The swing past the new detent ``target`` [rad] in ``direction`` (in panel steps ``step`` [rad]) and
        its time after the step [s], where the panel rests at the end off the detent: whole steps (``slip``, lost)
        and the rest [rad] (a load's lag), and the ring: the last time after the step it is farther than 5 % of a
        step from where it rests [s]."""
        time, panel = np.concatenate(self.rows).T
        if not len(time):
            return {"overshoot": 0.0, "overshoot_time": 0.0, "rest": 0.0, "slip": 0.0, "ring": 0.0}
        past = direction * (panel - target)
        k = int(np.argmax(past))
        off = np.abs(panel - panel[-1]) > 0.05 * step
        slip = PHASES * float(np.rint((panel[-1] - target) / step / PHASES))  # whole electrical periods off (lost)
        return {
            "overshoot": float(past[k]) / step,
            "overshoot_time": float(time[k]) - STEP_AT,
            "rest": float(panel[-1]) - target - slip * step,
            "slip": slip,
            "ring": float(time[off].max(initial=STEP_AT)) - STEP_AT,
        }


def transient(prep, angle: float, index: int, direction: int, window: float) -> dict:
    """One step (``direction`` 0: none) from index ``index`` held at panel angle ``angle`` [rad], simulated
    over ``window`` [s] through the master as ``run_scenario`` sets it up: its figures."""
    from heliostep.cosim import SimulationError
    from heliostep.drive.inputs import implied_parameters
    from heliostep.drive.sequencer import StepSchedule
    from heliostep.results.figures.solution import SolutionRecorder
    from heliostep.run.bindings import parameters
    from heliostep.run.runner import _system

    scenario, sequencer = prep.scenario, prep.inputs.sequencer
    r, s = scenario.transmission.pinion_radius, scenario.transmission.lever_arm
    steps = [index + direction] if direction else []
    schedule = StepSchedule(np.array([STEP_AT] if direction else [], dtype=float), np.array(steps, dtype=int), index)
    current_a, current_b = sequencer.reference_currents(np.array([index, *steps]))
    start = float(np.arctan(np.tan(angle) - sequencer.position(index) * r / s))  # the panel at rotor 0
    implied = implied_parameters(scenario, sequencer, schedule, (current_a[0], current_b[0]), start, None)
    end = index + direction
    target = float(np.arctan(np.tan(start) + sequencer.position(end) * r / s))
    ends, references = np.array([0.0, window]), (np.full(2, target), np.full(2, float(sequencer.position(end))))
    timing = dict(
        duration=window, reference_times=ends, output_times=ends, schedule=schedule, implied_parameters=implied
    )
    drive = dict(panel_angle_ref=references[0], rotor_angle_ref=references[1], current_a_ref=current_a)
    inputs = dataclasses.replace(prep.inputs, **timing, **drive, current_b_ref=current_b)
    values = parameters(scenario, inputs, prep.roles, prep.infos)
    system = _system(scenario, prep.infos, inputs, values, prep.roles, None)
    outputs = [f"{name}.{output}" for name, info in system.fmus.items() for output in info.traced_outputs]
    columns = ["time", *[item.name for item in system.inputs], *outputs]
    recorder = SolutionRecorder(columns, prep.roles, sequencer, schedule, None)
    step = abs(target - angle) if direction else 1.0  # the panel's step between the two detents
    watch = _Watch(recorder, columns.index(prep.roles["panel_angle"]))
    try:
        system.simulate(0.0, window, ends, prep.solver, monitor=watch)
    except SimulationError:  # the drive runs away: an outcome the family cannot give (a full run must)
        return {**dict.fromkeys(FIELDS, np.nan), "slip": 0.0, "missed": 1.0, "lost": 1.0, "failed": 1.0, "ring": window}
    figures = recorder.figures()
    return {
        "peak_torque": figures["peak_torque_Nm"],
        "peak_current": figures["peak_phase_current_A"],
        "energy": figures["electrical_energy_J"],
        **watch.motion(target, direction or 1, step),
        "missed": figures["missed_steps"] if direction else 0,
        "lost": figures["steps_lost"],
        "failed": 0.0,
    }


@dataclasses.dataclass
class Family:
    """A drive's step family: each figure per (panel angle, direction -1/+1, phase), the holding energy rate."""

    angles: np.ndarray
    table: dict
    holding_power: np.ndarray  # [W] per phase
    cpu_s: float
    transients: int

    def at(self, name: str, angle: np.ndarray, direction: np.ndarray, phase: np.ndarray) -> np.ndarray:
        """The figure at each step's condition: a cubic spline in the panel angle (a peak's maximum is smooth);
        an outcome (missed, lost, failed) the worse of the two family angles around the step's."""
        from scipy.interpolate import CubicSpline

        table = self.table[name]
        if name == "slip":  # signed whole steps: the nearest family angle's
            values = table[np.rint(np.interp(angle, self.angles, np.arange(len(self.angles)))).astype(int)]
        elif name in ("missed", "lost", "failed"):
            right = np.clip(np.searchsorted(self.angles, angle), 1, len(self.angles) - 1)
            values = np.maximum(table[right - 1], table[right])  # (steps, direction, phase)
        else:  # a transient that failed (nan) falls back anyway: its neighbours' largest value stands in
            table = np.where(np.isfinite(table), table, np.nanmax(table, initial=0.0))
            values = CubicSpline(self.angles, table, axis=0)(angle)  # (steps, direction, phase)
        return values[np.arange(len(angle)), (direction > 0).astype(int), phase]


def build_family(scenario, angles: np.ndarray, window: float) -> Family:
    """The step family of the case's drive over ``angles`` [rad], its run set up (FMUs, roles, parameters,
    solver) as ``run_scenario`` sets it up, on a one-second window."""
    from heliostep.run.runner import _prepare
    from heliostep.scenario import validate_scenario

    started = time.process_time()
    data = scenario.resolved_dict()
    data["window"] = {"date": data["window"]["date"], "start": "12:00", "duration": 1.0}
    short = validate_scenario(data, source=scenario.source, folder=scenario.folder)
    prep = _prepare(short, None, time.perf_counter(), keep_trace=False)
    table = {name: np.zeros((len(angles), 2, PHASES)) for name in FIELDS}
    middle = float(angles[len(angles) // 2])
    holding = np.array([transient(prep, middle, p, 0, window)["energy"] / window for p in range(PHASES)])
    for i, angle in enumerate(angles):
        for d, direction in enumerate((-1, 1)):
            for p in range(PHASES):
                figures = transient(prep, float(angle), p, direction, window)
                figures["energy"] -= holding[p] * window
                for name in FIELDS:
                    table[name][i, d, p] = figures[name]
    count = PHASES + len(angles) * 2 * PHASES
    return Family(angles, table, holding, time.process_time() - started, count)


def stepped(inputs, scenario, slip=0.0) -> tuple[np.ndarray, np.ndarray]:
    """(index held, panel angle held [rad]) from the start and after each step: the transmission from the start,
    the rotor ``slip`` whole steps (lost) off the index's detent."""
    schedule, sequencer = inputs.schedule, inputs.sequencer
    held = np.concatenate([[schedule.initial_index], schedule.indices])
    r, s = scenario.transmission.pinion_radius, scenario.transmission.lever_arm
    return held, np.arctan(np.tan(inputs.panel_angle_ref[0]) + sequencer.position(held + slip) * r / s)


def compose(scenario, family: Family, light_every: float) -> tuple[dict, tuple, float]:
    """(composed figures, CPU seconds of the schedule, the figures and the light, the shortest step interval
    [s]) of a case from its family."""
    from heliostep.drive.inputs import prepare_inputs

    started = time.process_time()
    inputs = prepare_inputs(scenario)
    prepared = time.process_time()
    times = inputs.schedule.times
    held, commanded = stepped(inputs, scenario)
    direction, phase, angle = np.diff(held), np.mod(held[:-1], PHASES), commanded[:-1]
    lost = np.zeros(len(held))
    for _ in range(2):  # the steps' angles with the steps lost before them, from the commanded ones on
        at = {name: family.at(name, angle, direction, phase) for name in FIELDS}
        lost = np.concatenate([[0.0], np.cumsum(at["slip"])])  # the whole steps lost so far, after each step
        detents = stepped(inputs, scenario, lost)[1]
        angle = detents[:-1]
    targets = stepped(inputs, scenario, np.concatenate([lost[:1], lost[:-1]]))[1][1:]  # each step's, as it starts
    rest = at["rest"]  # [rad] where the panel rests off each detent (a load's lag): the first one as the next
    panel = detents + np.concatenate([rest[:1] if len(rest) else [0.0], rest])
    bounds = np.concatenate([[0.0], times, [inputs.duration]])
    holding = float(np.sum(family.holding_power[np.mod(held, PHASES)] * np.diff(bounds)))
    energy = holding + float(at["energy"].sum())
    reference = inputs.panel_reference()
    swing = direction * at["overshoot"] * np.abs(np.diff(commanded))
    parts = {
        "interval start": panel - reference(bounds[:-1]),  # before each step's swing
        "trigger": panel - reference(bounds[1:]),  # the interval's end: the reference at the next step's trigger
        "swing": targets + swing - reference(times + at["overshoot_time"]),  # each step's swing past its target
        "reference turn": panel[np.searchsorted(times, inputs.reference_times, side="right")] - inputs.panel_angle_ref,
    }
    errors = np.concatenate(list(parts.values()))
    worst = int(np.argmax(np.abs(errors)))
    part = next(name for name, n in zip(parts, np.cumsum([len(v) for v in parts.values()]), strict=True) if worst < n)
    figures: dict = {
        "peak_torque_Nm": float(at["peak_torque"].max(initial=0.0)),
        "peak_phase_current_A": float(at["peak_current"].max(initial=0.0)),
        "electrical_energy_J": energy,
        "max_tracking_error_deg": float(np.degrees(np.abs(errors).max())),
        "missed_steps": int(np.rint(at["missed"]).sum()),
        "steps_lost": int(np.rint(at["lost"]).sum()),
    }
    offset = np.abs(at["rest"] - family.at("rest", angle, -direction, phase)) / np.abs(np.diff(commanded))
    figures["fallback"] = fallback(
        family, angle, np.diff(bounds), at, offset * (np.diff(direction, prepend=direction[:1]) != 0)
    )
    top = {name: int(np.argmax(at[key])) if len(angle) else 0 for name, key in PEAKS.items()}
    figures["decided"] = {name: f"step at {np.degrees(angle[k]):.1f} deg" for name, k in top.items() if len(angle)}
    figures["decided"]["max_tracking_error_deg"] = part
    figures["decided"]["electrical_energy_J"] = f"holding {holding / energy:.6f}, steps {1 - holding / energy:.1e}"
    composed = time.process_time()
    figures["light_energy_J"] = composed_light(scenario, inputs, panel, light_every)
    shortest = float(np.diff(times).min()) if len(times) > 1 else float("inf")
    done = time.process_time()
    return figures, (prepared - started, composed - prepared, done - composed), shortest


def fallback(family: Family, angle: np.ndarray, intervals: np.ndarray, at: dict, reversal: np.ndarray) -> str:
    """Where the case leaves what a family assumes (a production module co-simulates those stretches in full):
    a step outside the family's angles, a step before the previous one's ring has died out, a step whose transient
    failed, a step after a reversal that starts off the family's settled start by over 1 % of a step (``reversal``:
    the family's rests after the two directions apart, in steps: friction that sticks, a creep cut short); "none"
    when it stays within (steps missed and lost are composed: the family's outcomes)."""
    reasons = []
    if np.any(reversal > 0.01):
        reasons.append(
            f"{int(np.sum(reversal > 0.01))} reversals start off the detent by {reversal.max():.1%} of a step"
        )
    if len(angle) and (angle.min() < family.angles[0] or angle.max() > family.angles[-1]):
        reasons.append("outside the family's angles")
    if len(angle) and np.any(intervals[1:-1] < at["ring"][1:]):
        reasons.append(f"{int(np.sum(intervals[1:-1] < at['ring'][1:]))} steps within the ring")
    if np.any(at["failed"] > 0):
        reasons.append(f"{int(np.sum(at['failed'] > 0))} steps the family could not simulate (the drive runs away)")
    return "; ".join(reasons) or "none"


def composed_light(scenario, inputs, panel: np.ndarray, every: float) -> float:
    """``light_energy_J`` of heliostep's light figures (as a sweep's case: no first-order terms) on the stepped
    panel angle, on the case's output grid taken every ``every`` seconds (and its last row)."""
    from heliostep.results.light.on_tube import LightIntegrals
    from heliostep.results.trace.frame import drive_metadata

    roles = scenario.resolved_roles()
    grid = inputs.output_times
    grid = np.unique(np.concatenate([grid[:: max(1, round(every / scenario.output.interval))], grid[-1:]]))
    held = np.searchsorted(inputs.schedule.times, grid, side="right")
    trace = pd.DataFrame(
        {"time": grid, "panel_angle_ref": inputs.panel_reference()(grid), roles["panel_angle"]: panel[held]}
    )
    drive = {**drive_metadata(inputs), "step_times": []}  # no marks: no solution to correct between the rows with
    metadata = {"window_start": inputs.window_start.isoformat(), "roles": roles, "drive": drive}
    light = LightIntegrals(metadata, scenario, first_order=False)
    light(trace)
    return float(light.figures()["light_energy_J"])


def deviation(full, composed, name: str) -> float:
    if full is None or np.isnan(full):
        return np.nan
    if name in ("missed_steps", "steps_lost"):
        return float(abs(composed - full))
    return abs(composed - full) / abs(full) if full else float(abs(composed))


def print_case(label: str, summary: dict | None, composed: dict, full_s: float, costs: tuple, shortest: float):
    print(
        f"\n{label}: full {full_s:.2f} s CPU, composed {sum(costs):.3f} s CPU ({full_s / sum(costs):.0f}x: "
        f"schedule {costs[0]:.3f}, figures {costs[1]:.3f}, light {costs[2]:.3f}); "
        f"shortest step interval {shortest:.3f} s; fall back: {composed['fallback']}"
    )
    print(f"  {'figure':24} {'full':>14} {'composed':>14} {'deviation':>10} {'tolerance':>9}  holds  composed from")
    for name, tolerance in TOLERANCES.items():
        full, mine = np.nan if summary is None else summary[name], composed[name]
        dev = deviation(full, mine, name)
        holds = "-" if np.isnan(dev) else "yes" if dev <= tolerance else "NO"
        where = composed["decided"].get(name, "")
        print(f"  {name:24} {full:14.7g} {mine:14.7g} {dev:10.2e} {tolerance:9.1e}  {holds:5}  {where}")


def panel_range(scenarios) -> tuple[float, float]:
    """The smallest and largest panel angle held [rad] over the cases' steps."""
    from heliostep.drive.inputs import prepare_inputs

    held = [stepped(prepare_inputs(scenario), scenario)[1] for scenario in scenarios]
    return float(min(p.min() for p in held)), float(max(p.max() for p in held))


def print_family(kind: str, family: Family) -> None:
    print(
        f"family {kind}: {family.transients} transients, {family.cpu_s:.2f} s CPU, "
        f"panel {np.degrees(family.angles[0]):.2f} .. {np.degrees(family.angles[-1]):.2f} deg, "
        f"holding {family.holding_power.mean():.5f} W"
    )
    for name in FIELDS:
        values = family.table[name]
        spread = np.ptp(values, axis=2).max()  # over the phase transitions, at the same angle and direction
        print(f"  {name:16} min {values.min():11.5g} max {values.max():11.5g} phase spread {spread:9.3g}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--days", type=int, nargs="+", default=[80, 172, 355])
    parser.add_argument("--mirrors", type=int, nargs="+", default=[0, 9])
    parser.add_argument("--angles", type=int, default=13)
    parser.add_argument("--window", type=float, default=1.0)
    parser.add_argument("--light-every", type=float, default=10.0)
    parser.add_argument("--set", action="append", default=[], metavar="KEY=VALUE")
    parser.add_argument("--scenario", help="a scenario file studied alone instead of the year-field's cases")
    args = parser.parse_args()
    kinds = study_kinds(args)
    families: dict[str, Family] = {}
    full_cpu: dict[str, list[float]] = {}
    composed_cpu: dict[str, list[float]] = {}
    worst = dict.fromkeys(TOLERANCES, 0.0)
    for kind, members in kinds.items():
        low, high = panel_range([scenario for _, scenario in members])
        margin = 0.02 * (high - low) + np.radians(1.0)
        families[kind] = build_family(members[0][1], np.linspace(low - margin, high + margin, args.angles), args.window)
        print_family(kind, families[kind])
        for label, scenario in members:
            summary, full_s = full_run(scenario)
            composed, costs, shortest = compose(scenario, families[kind], args.light_every)
            print_case(label, summary, composed, full_s, costs, shortest)
            full_cpu.setdefault(kind, []).append(full_s)
            composed_cpu.setdefault(kind, []).append(sum(costs))
            for name in TOLERANCES:
                worst[name] = max(worst[name], deviation(summary and summary[name], composed[name], name))
    if args.scenario is None:
        print_year(families, full_cpu, composed_cpu, worst)


def study_kinds(args) -> dict[str, list]:
    """The studied cases by kind of drive: (label, scenario) of the year-field's cases (``--days`` x ``--mirrors``
    and each day's shared primary, as the sweep builds them, ``--set`` added to its overrides), or ``--scenario``'s."""
    import yaml

    from heliostep.scenario import load_scenario, validate_scenario
    from heliostep.sweep.axes import SweepAxis
    from heliostep.sweep.spec import expand_cases, load_sweep

    if args.scenario is not None:
        scenario = load_scenario(args.scenario, overrides=tuple(args.set))
        return {"scenario": [(scenario.name, scenario)]}
    spec = load_sweep(SWEEP)
    axes = (SweepAxis("day_of_year", tuple(args.days)), SweepAxis("mirror", tuple(args.mirrors)))
    more = tuple((key, yaml.safe_load(value)) for key, _, value in (item.partition("=") for item in args.set))
    kinds: dict[str, list] = {}
    for case in expand_cases(dataclasses.replace(spec, axes=axes, overrides=spec.overrides + more)):
        kind, columns = case.columns["role"], case.columns
        scenario = validate_scenario(case.scenario, source=case.source, folder=case.folder)
        kinds.setdefault(kind, []).append(
            (f"day {columns['day_of_year']} {kind} mirror {columns['mirror_index']}", scenario)
        )
    return kinds


def print_year(families: dict, full_cpu: dict, composed_cpu: dict, worst: dict) -> None:
    """The year-field (365 days x 13 mirrors + 365 shared primaries) extrapolated from the cases' mean CPU."""
    counts = {"drive": 365 * 13, "shared-primary": 365}
    full = sum(counts[k] * np.mean(v) for k, v in full_cpu.items()) / 3600
    composed = sum(counts[k] * np.mean(v) for k, v in composed_cpu.items()) / 3600
    family = sum(f.cpu_s for f in families.values()) / 3600
    print("\nworst deviation: " + ", ".join(f"{k} {v:.2e}" for k, v in worst.items()))
    minutes = f"families {family * 60:.1f} min + composition {composed * 60:.1f} min"
    print(f"year-field: {family + composed:.3f} core-hours ({minutes}), {full:.2f} core-hours (full)")


if __name__ == "__main__":
    main()
