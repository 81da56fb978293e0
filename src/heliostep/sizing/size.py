"""``heliostep size``: every candidate drive and current against a scenario's load, and the verdict.

Details: docs/sizing.md, ``heliostep.sizing.size``.
"""

from __future__ import annotations

import copy
import datetime as dt
import functools
import hashlib
import math
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path

import numpy as np

from heliostep.drive.wind import air_density, panel_wind_moment
from heliostep.errors import InputError
from heliostep.progress import progress_bar
from heliostep.run import resolve_fmus
from heliostep.run.load_budget import mechanics_values
from heliostep.scenario import Scenario, resolve_scenario_path, validate_scenario
from heliostep.scenario.catalogue import MotorCandidate, motor_overrides, role_instance, shipped_catalogue_path
from heliostep.scenario.keys import apply_overrides
from heliostep.scenario.yaml_io import read_yaml_file
from heliostep.sizing.band import corner_parameters, drive_at, worst_corner
from heliostep.sizing.case import run_sizing_case
from heliostep.sizing.composed import compose_days
from heliostep.sizing.days import date_of, select_days
from heliostep.sizing.inputs import check_wind_given, file_digest, sizing_inputs
from heliostep.sizing.plan import SizingCase, SizingPlan, check_case_count, check_cases
from heliostep.sizing.pool import CurveTask, on_every_core
from heliostep.sizing.stow import stow_angles, stow_step_rates
from heliostep.sizing.verdict import judge
from heliostep.sweep.band import load_ranges
from heliostep.sweep.certificate import CERTIFICATE_CASES
from heliostep.sweep.spec import MAX_CASES
from heliostep.sweep.worker import FmuPayload

__all__ = [
    "DEFAULT_CURVE_RATES",
    "DEFAULT_SAFETY_FACTOR",
    "SizingCase",
    "SizingPlan",
    "design_gust_moment",
    "judge_candidates",
    "plan_sizing",
    "run_sizing_case",
    "run_sizing_cases",
]

#: The paper's margin, here on the load (the paper put it on the motor's transient peak).
DEFAULT_SAFETY_FACTOR = 2.0
#: Step rates of each candidate's speed-torque curve on the sheet [full steps/s].
DEFAULT_CURVE_RATES = (5.0, 500.0, 1000.0, 2000.0, 3000.0)


def design_gust_moment(scenario: Scenario, gust_speed: float) -> float:
    """The largest moment on the panel axis [N.m] a design gust of ``gust_speed`` [m/s] puts on the
    scenario's mirror, at the panel's worst angle to the wind: max over theta_p of
    |C_M(theta_p)| 1/2 rho v^2 A c (:func:`heliostep.drive.wind.panel_wind_moment`: its cited moment
    coefficient; A the mirror's aperture, c its width across the axis; rho the site's air density at
    ``wind.air_temperature``, ISA's without one). A design gust is a peak speed: no gust factor."""
    angles = np.radians(np.linspace(0.0, 90.0, 9001))  # C_M's peak lies inside (25.5 deg): found to 0.01 deg
    density = air_density(scenario.site.altitude, scenario.wind.air_temperature)
    optics = scenario.optics
    moments = panel_wind_moment(gust_speed, angles, optics.aperture_area, optics.mirror_width, density, 1.0)
    return float(np.max(np.abs(moments)))


def _speed_source(scenario: Scenario) -> str:
    wind = scenario.wind
    if wind.weather_file is not None:
        return f"wind.weather_file {wind.weather_file}"
    return "wind.speed" if wind.speed is not None else "wind.profile"


def _instance(scenario: Scenario, role: str, default: str) -> str:
    return role_instance(scenario, role, default)


def _case_overrides(
    scenario: Scenario, candidate: MotorCandidate, current: float, day: dt.date, wind: float | None
) -> tuple[str, ...]:
    """A case's ``--set`` items; ``wind``: the design moment [N.m], which replaces the scenario's wind
    speed source (if any), or None: the scenario's wind over time as it is."""
    return (
        *motor_overrides(scenario, candidate),  # the same items as heliostep run --motor
        f"sequencer.current={current!r}",
        f"window.date={day.isoformat()}",
        *(() if wind is None else _design_wind(scenario, wind)),
    )


def _design_wind(scenario: Scenario, wind: float) -> tuple[str, ...]:
    """The design moment as the case's wind: the constant ``wind.moment``, the speed sources off."""
    sources = [key for key in ("speed", "weather_file", "profile") if getattr(scenario.wind, key) is not None]
    return (*(f"wind.{key}=null" for key in sources), f"wind.moment={wind!r}")


def _check_options(design_gust, days, safety_factor: float, curve_rates: Sequence[float], max_cases) -> None:
    """The options' values, InputError naming the option."""
    if isinstance(max_cases, bool) or not isinstance(max_cases, int) or max_cases < 1:
        raise InputError(f"--max-cases {max_cases!r}: expected a whole number of cases >= 1")
    if design_gust is not None and not (math.isfinite(design_gust) and design_gust >= 0):
        raise InputError(f"--design-gust {design_gust!r}: expected a wind speed >= 0 [m/s]")
    if not (math.isfinite(safety_factor) and safety_factor > 0):
        raise InputError(f"--safety-factor {safety_factor!r}: expected > 0")
    if any(not (math.isfinite(rate) and rate > 0) for rate in curve_rates):
        raise InputError(f"--curve-rates {list(curve_rates)}: expected step rates > 0 [full steps/s]")
    bad_days = [] if isinstance(days, str) else [day for day in days if not 1 <= day <= 365]
    if bad_days:
        raise InputError(f"--days {bad_days[0]!r}: expected a day of the year, 1..365")


def plan_sizing(
    scenario_path: str | Path,
    candidates: Sequence[MotorCandidate],
    *,
    design_gust: float | None = None,
    days: Sequence[int] | str = (),
    safety_factor: float = DEFAULT_SAFETY_FACTOR,
    curve_rates: Sequence[float] = DEFAULT_CURVE_RATES,
    overrides: Sequence[str] = (),
    band_days: bool = True,
    catalogue: str | Path | None = None,
    max_cases: int = MAX_CASES,
) -> SizingPlan:
    """Every case of the sizing, each case's scenario validated (an :class:`InputError` before any run).
    ``days``: days of the year, ``"all"``, or empty for the selection of :mod:`heliostep.sizing.days`;
    ``overrides``: ``--set``-style items applied to the scenario first; ``band_days``: every day co-simulated
    once more with the drive physics' ranges at their worst corner (after all the nominal cases), for the
    band's steps missed and lost and tracking error. ``catalogue``: the file ``candidates`` came from (None: the
    shipped one), named when they make more than ``max_cases`` cases (refused before any is built); the largest
    case's estimate is refused over the scenario's budget."""
    path = resolve_scenario_path(scenario_path)
    scenario_digest = file_digest(path, "scenario")  # the file as read next
    raw = read_yaml_file(path, "scenario")
    if not isinstance(raw, dict):
        raise InputError(f"{path}: the top level must be a mapping of keys (name, site, window, ...)")
    raw = apply_overrides(raw, overrides, str(path))
    scenario = validate_scenario(copy.deepcopy(raw), source=str(path), folder=path.absolute().parent)
    _check_options(design_gust, days, safety_factor, curve_rates, max_cases)
    check_wind_given(str(path), raw, design_gust)
    wind, source = _plan_wind(scenario, design_gust)
    selection = select_days(scenario, days)
    rates = tuple(sorted(float(rate) for rate in curve_rates))
    plan = SizingPlan(
        scenario,
        raw,
        path.absolute().parent,
        list(candidates),
        selection.days,
        None if wind is None else float(wind),
        source,
        safety_factor,
        rates,
    )
    plan.day_selection = selection
    plan.ranges = load_ranges()
    plan.corner = _band_corner(plan) if band_days else {}
    source = str(catalogue if catalogue is not None else shipped_catalogue_path())
    check_case_count(source, plan.candidates, plan.days, bool(plan.corner), max_cases)  # before any is built
    plan.inputs = _inputs(plan, scenario_digest, source, overrides, design_gust)
    plan.cases = _plan_cases(plan)
    check_cases(plan)  # every case's scenario valid and the largest within the budget before anything runs
    plan.fmu_paths = resolve_fmus(scenario)
    mechanics = _instance(scenario, "wind_moment", "mechanics")
    plan.mechanics = mechanics_values(scenario, mechanics, plan.fmu_paths[mechanics])
    return plan


def _inputs(
    plan: SizingPlan, scenario_digest: str, catalogue: str, overrides: Sequence[str], design_gust: float | None
) -> dict:
    """The sheet's ``inputs`` (:func:`heliostep.sizing.inputs.sizing_inputs`), the catalogue's digest read now."""
    return sizing_inputs(
        plan.scenario,
        scenario_digest=scenario_digest,
        catalogue=str(Path(catalogue).absolute()),
        catalogue_digest=file_digest(catalogue, "motor catalogue"),
        overrides=overrides,
        design_gust=design_gust,
        wind_moment=plan.wind_moment,
        wind_source=plan.wind_source,
        safety_factor=plan.safety_factor,
        days=plan.day_selection.record() if plan.day_selection is not None else {},
    )


def _plan_wind(scenario: Scenario, design_gust: float | None) -> tuple[float | None, str]:
    """The sizing's wind: the design gust's moment [N.m], the scenario's constant ``wind.moment``, or None
    (the scenario's wind over time, each day's own); and its source in words."""
    if design_gust is not None:
        replaced = [key for key in ("speed", "weather_file", "profile") if getattr(scenario.wind, key) is not None]
        instead = f" in place of the scenario's wind.{replaced[0]}" if replaced else ""
        return design_gust_moment(scenario, design_gust), f"design gust {design_gust:g} m/s{instead}"
    if scenario.wind.has_speed:
        return None, f"{scenario.source}: the wind over time ({_speed_source(scenario)}), each day's own"
    return scenario.wind.moment, f"{scenario.source}: wind.moment"


def _band_corner(plan: SizingPlan) -> dict[str, float]:
    """The worst corner's values the band's days set on the scenario's FMUs; none where the ranges name no
    parameter of its motor (those days would be the nominal ones again)."""
    corner = corner_parameters(worst_corner(plan.ranges), list(plan.scenario.fmus))
    motor = _instance(plan.scenario, "torque", "motor")
    return corner if any(key.startswith(f"parameters.{motor}.") for key in corner) else {}


def _plan_cases(plan: SizingPlan) -> list[SizingCase]:
    """Every candidate, current and day; with a band corner (:attr:`SizingPlan.corner`) the same again at
    it, after all the nominal ones."""
    scenario, year, cases = plan.scenario, plan.scenario.window.date.year, []
    corner = tuple(f"{key}={value!r}" for key, value in plan.corner.items())
    for at_corner in (False, True) if corner else (False,):
        for candidate in plan.candidates:
            for current in candidate.currents:
                for day in plan.days:
                    overrides = _case_overrides(scenario, candidate, current, date_of(year, day), plan.wind_moment)
                    overrides += corner if at_corner else ()  # after the candidate's own bus and loop gain
                    cases.append(SizingCase(candidate.name, current, day, overrides, at_corner))
    return cases


def run_sizing_cases(
    plan: SizingPlan,
    *,
    scheduler: str | None = None,
    progress: bool = False,
    should_stop: Callable[[], bool] | None = None,
    on_case: Callable[[str, dict], None] | None = None,
    exact: bool = False,
    certify: int = CERTIFICATE_CASES,
    seed: int = 0,
) -> dict[str, dict]:
    """Run the plan's cases: those step families compose (:func:`heliostep.sizing.composed.compose_days`,
    certified by ``certify`` cases drawn by ``seed``; ``exact``: none), the rest co-simulated (on Dask with
    ``scheduler``, else a case a task on every core, :func:`heliostep.sizing.pool.on_every_core`); case key ->
    its record. Stopped part-way, it returns the cases finished so far (a stop begins no case more and lets
    those under way finish). ``on_case(key, record)`` is called as each case finishes."""
    results: dict[str, dict] = {}
    bar = progress_bar(len(plan.cases), "sizing cases", "case", progress)
    source, folder = plan.scenario.source, str(plan.folder)

    def finished(case: SizingCase, record: dict) -> None:
        results[case.key] = record
        bar.update(1)
        if on_case is not None:
            on_case(case.key, record)

    try:
        left: list[tuple[SizingCase, str | None]] = [(case, None) for case in plan.cases]
        if not exact:
            left = list(compose_days(plan, finished, should_stop, certify, seed))
        if scheduler:
            _run_on_dask(plan, left, scheduler, results, bar, should_stop, on_case)
            return results
        why = {case.key: (case, reason) for case, reason in left}
        tasks = {
            case.key: functools.partial(run_sizing_case, plan.raw, case.overrides, source, folder, None, plan.fmu_paths)
            for case, _ in left
        }  # each day in full a task on every core, a stop beginning none more
        on_every_core(
            tasks, should_stop, on_done=lambda key, record: finished(why[key][0], {**record, "fallback": why[key][1]})
        )
    finally:
        bar.close()
    return results


def _run_on_dask(plan: SizingPlan, left, scheduler: str, results: dict, bar, should_stop, on_case) -> None:
    """The cases on the scheduler's workers, collected as they finish; the rest cancelled on a stop."""
    from distributed import as_completed

    from heliostep.sweep.cluster import _dask_client

    source, folder = plan.scenario.source, str(plan.folder)
    payloads = {}
    for instance, path in plan.fmu_paths.items():
        data = Path(path).read_bytes()
        payloads[instance] = FmuPayload(name=Path(path).name, sha256=hashlib.sha256(data).hexdigest(), data=data)
    with _dask_client(scheduler=scheduler) as client:
        [shipped] = client.scatter([payloads], broadcast=True)
        futures = {
            client.submit(run_sizing_case, plan.raw, case.overrides, source, folder, None, None, shipped, pure=False): (
                case,
                reason,
            )
            for case, reason in left
        }
        for future in as_completed(list(futures)):
            if should_stop is not None and should_stop():
                client.cancel(list(futures))
                break
            case, reason = futures[future]
            key = case.key
            results[key] = {**future.result(), "fallback": reason}
            bar.update(1)
            if on_case is not None:
                on_case(key, results[key])


def _curve_tasks(plan: SizingPlan, worst: bool = False, angles: np.ndarray | None = None) -> dict[str, CurveTask]:
    """Each candidate's speed-torque curve at its largest current, on its bus, to co-simulate; ``worst``: at
    the ranges' worst corner (:func:`heliostep.sizing.band.worst_corner`); ``angles``: a stow move's
    panel angles [rad], whose highest step rate joins the curve's rates (the stow margin's point)."""
    mode, microsteps = plan.scenario.sequencer.mode, plan.scenario.sequencer.microsteps
    motor = _instance(plan.scenario, "torque", "motor")
    corner = worst_corner(plan.ranges) if worst else {}
    tasks = {}
    for c in plan.candidates:
        stow_rates = stow_step_rates(plan, c, angles)
        rates = sorted({*plan.curve_rates, *([float(np.max(stow_rates))] if len(stow_rates) else [])})
        tasks[c.name] = CurveTask(drive_at(c.drive(), corner, motor), c.currents[-1], tuple(rates), mode, microsteps)
    return tasks


def judge_candidates(
    plan: SizingPlan, results: Mapping[str, dict], curves: bool = True, should_stop: Callable[[], bool] | None = None
) -> dict:
    """The sizing sheet's content: per candidate and current, the figures and the verdict; with ``curves``
    each candidate's speed-torque curve, nominal and at the ranges' worst corner (co-simulated on every core,
    :func:`~heliostep.sizing.pool.on_every_core`; none when ``should_stop`` says so before they are all done)."""
    if not curves:
        return judge(plan, results, {}, {})
    angles = stow_angles(plan)  # the worst corner's curve too is co-simulated at the stow rate, not interpolated
    tasks = {("nominal", name): task for name, task in _curve_tasks(plan, angles=angles).items()}
    if plan.ranges:
        tasks.update({("worst", name): task for name, task in _curve_tasks(plan, True, angles).items()})
    done, stopped = on_every_core(tasks, should_stop)
    if stopped:
        return judge(plan, results, {}, {})
    nominal = {name: done[kind, name] for kind, name in tasks if kind == "nominal"}
    worst = {name: done[kind, name] for kind, name in tasks if kind == "worst"}
    return judge(plan, results, nominal, worst, angles)
