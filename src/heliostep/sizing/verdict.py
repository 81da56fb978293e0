"""The sizing's verdicts: each candidate and current judged on its load budget, margins and simulated days.

See :mod:`heliostep.sizing.size` for what is judged. Candidates are ordered from the smallest (lowest
datasheet holding torque) up, and currents from the lowest; the smallest passing pair is the
recommendation, and every pair before it is listed with the reasons it fails.
"""

from __future__ import annotations

import datetime as dt
import math
from collections.abc import Mapping

import numpy as np

from heliostep.drive.inputs import prepare_inputs
from heliostep.run.load_budget import LoadBudget, load_budget, static_step_limit, wind_moment_at
from heliostep.run.speed_torque import SpeedTorqueCurve
from heliostep.scenario.catalogue import MotorCandidate
from heliostep.sizing.band import drive_at, margin_band, worst_corner
from heliostep.sizing.days import date_of, day_windows
from heliostep.sizing.plan import SizingPlan, case_scenario
from heliostep.sizing.stow import stow_angles, stow_margin

__all__ = ["ENERGY_ESTIMATORS", "MARGIN_CASES", "judge", "verdict_summary"]

#: How the drive's energy per year is estimated from the simulated days, by the kind of day selection.
ENERGY_ESTIMATORS = {
    "selected": (
        "365 x the mean drive energy per day of the simulated days; the days are the year's most demanding "
        "(the sun's fastest, the windiest), so this is an upper estimate of the year's energy, not a proven bound"
    ),
    "all": "the sum of the 365 days' drive energy per day (365 x their mean)",
    "given": "365 x the mean drive energy per day of the days given (as representative as they are)",
}


def _ratio(capacity: float, load: float) -> float:
    return math.inf if load <= 0 else capacity / load


def _budgets(plan: SizingPlan, candidate: MotorCandidate) -> dict[int, LoadBudget]:
    """The load budget of each day (the reference does not depend on the current): the design moment, or
    the day's wind over time at each reference instant (its stow moves in the reference)."""
    budgets = {}
    for case in plan.cases:
        if case.candidate == candidate.name and not case.at_worst_corner and case.day_of_year not in budgets:
            scenario = case_scenario(plan.raw, case.overrides, plan.scenario.source, plan.folder)
            inputs = prepare_inputs(scenario)
            wind = wind_moment_at(inputs) if plan.wind_moment is None else plan.wind_moment
            budgets[case.day_of_year] = load_budget(scenario, inputs, wind, plan.mechanics, candidate.rotor_inertia)
    return budgets


def _simulated(
    plan: SizingPlan, candidate: MotorCandidate, current: float, results: Mapping[str, dict], at_worst_corner=False
) -> dict:
    """The co-simulated days of one candidate and current, summed up (``at_worst_corner``: the band's days)."""
    days = [
        case
        for case in plan.cases
        if case.candidate == candidate.name and case.current == current and case.at_worst_corner == at_worst_corner
    ]
    finished = [(case, results[case.key]) for case in days if case.key in results]
    ok = [(case, record) for case, record in finished if record.get("complete")]
    failed = [(case.day_of_year, record.get("error", "")) for case, record in finished if not record.get("complete")]
    energies = [
        record["drive_energy_per_day_J"] for _, record in ok if record.get("drive_energy_per_day_J") is not None
    ]
    errors = [record["max_tracking_error_deg"] for _, record in ok if record.get("max_tracking_error_deg") is not None]
    kind = plan.day_selection.kind if plan.day_selection is not None else "given"
    return {
        **_light(ok),
        "drive_energy_per_year_estimator": ENERGY_ESTIMATORS[kind],
        "days_simulated": [case.day_of_year for case, _ in ok],
        "days_unfinished": [case.day_of_year for case in days if case.key not in results],
        "days_failed": failed,
        "steps_commanded": sum(int(record.get("steps_commanded") or 0) for _, record in ok),
        "missed_steps": sum(int(record.get("missed_steps") or 0) for _, record in ok),
        "steps_lost": sum(int(record.get("steps_lost") or 0) for _, record in ok),
        "max_tracking_error_deg": max(errors) if errors else None,
        "electrical_energy_J": sum(float(record.get("electrical_energy_J") or 0.0) for _, record in ok),
        "drive_energy_per_day_J": sum(energies) / len(energies) if energies else None,
        "drive_energy_per_year_J": 365.0 * sum(energies) / len(energies) if energies else None,
        "drive_energy_per_year_kWh": 365.0 * sum(energies) / len(energies) / 3.6e6 if energies else None,
        "per_day": {str(case.day_of_year): record for case, record in finished},
    }


def _light(ok: list) -> dict:
    """The light on the receiver over the simulated windows against ideal tracking (both summed over the
    days [J]); the change includes the light lost while stowed (the actual light is the stowed panel's)."""
    pairs = [(r.get("light_energy_J"), r.get("light_energy_ideal_J")) for _, r in ok]
    pairs = [(float(a), float(i)) for a, i in pairs if a is not None and i is not None]
    actual, ideal = sum(a for a, _ in pairs), sum(i for _, i in pairs)
    stowed = [float(r["light_lost_stowed_J"]) for _, r in ok if r.get("light_lost_stowed_J") is not None]
    return {
        "light_energy_J": actual if pairs else None,
        "light_energy_ideal_J": ideal if pairs else None,
        "light_change_J": actual - ideal if pairs else None,
        "light_change_share": (actual - ideal) / ideal if pairs and ideal > 0 else None,
        "light_lost_stowed_J": sum(stowed),
    }


def _reasons(plan: SizingPlan, row: dict, budget: LoadBudget, day: int) -> list[str]:
    """Why a candidate at a current fails (empty: it passes)."""
    factor, reasons = plan.safety_factor, []
    if row["tracking_margin"] < factor:
        reasons.append(
            f"tracking margin {row['tracking_margin']:.2f} < {factor:g}: the motor steps from rest against at most "
            f"{row['static_step_limit_Nm']:.3g} N.m, the load is {budget.total_Nm:.3g} N.m (wind "
            f"{budget.wind_Nm:.3g}, friction {budget.friction_Nm:.3g}, inertia {budget.inertia_Nm:.2g} N.m) at "
            f"{budget.panel_angle_deg:.1f} deg panel angle on day {day}"
        )
    if row["idle_margin"] < factor:
        reasons.append(
            f"idle margin {row['idle_margin']:.2f} < {factor:g}: at idle current it holds "
            f"{row['idle_holding_torque_Nm']:.3g} N.m against a wind torque of {budget.wind_Nm:.3g} N.m on the shaft"
        )
    stow = row.get("stow_load")
    if row.get("stow_margin") is not None and row["stow_margin"] < factor and stow is not None:
        reasons.append(
            f"stow margin {row['stow_margin']:.2f} < {factor:g}: stowing at {stow['step_rate_per_s']:.3g} steps/s "
            f"it delivers {stow['deliverable_Nm']:.3g} N.m (pull-out {stow['pull_out_Nm']:.3g} N.m), the load is "
            f"{stow['total_Nm']:.3g} N.m (wind {stow['wind_Nm']:.3g} at {stow['stow_speed_m_s']:g} m/s, friction "
            f"{stow['friction_Nm']:.3g}, inertia {stow['inertia_Nm']:.2g} N.m) at {stow['panel_angle_deg']:.1f} deg"
        )
    simulated = row["simulation"]
    if simulated["steps_lost"] or simulated["missed_steps"]:
        reasons.append(
            f"{simulated['steps_lost']} steps lost and {simulated['missed_steps']} missed in the co-simulated days "
            f"{simulated['days_simulated']}"
        )
    for failed_day, error in simulated["days_failed"]:
        reasons.append(f"the co-simulation of day {failed_day} failed: {error}")
    return reasons


def _judge_current(
    plan: SizingPlan,
    candidate: MotorCandidate,
    current: float,
    budgets: dict,
    results: Mapping[str, dict],
    stow: tuple[SpeedTorqueCurve | None, np.ndarray | None] = (None, None),
    worst_curve: SpeedTorqueCurve | None = None,
) -> dict:
    drive, sequencer = candidate.drive(), plan.scenario.sequencer
    day, budget = max(budgets.items(), key=lambda item: item[1].total_Nm)
    step_limit = static_step_limit(drive, current, sequencer.mode, sequencer.microsteps)
    idle_holding = drive.holding_torque(current * sequencer.idle_current_fraction)
    row = {
        "current_A": current,
        "holding_torque_Nm": drive.holding_torque(current),
        "static_step_limit_Nm": step_limit,
        "idle_current_A": current * sequencer.idle_current_fraction,
        "idle_holding_torque_Nm": idle_holding,
        "load_budget": {**budget.record(), "day_of_year": day},
        "tracking_margin": _ratio(step_limit, budget.total_Nm),
        "idle_margin": _ratio(idle_holding, budget.wind_Nm),
        **(stow_margin(plan, candidate, current, step_limit, *stow) or {"stow_margin": None, "stow_load": None}),
        "simulation": _simulated(plan, candidate, current, results),
    }
    if plan.ranges:
        motor = plan.scenario.resolved_roles().get("torque", "motor").partition(".")[0]
        row["band"] = margin_band(drive, current, budget, plan.ranges, sequencer, motor)
        worst_stow = _worst_corner_stow(plan, candidate, current, stow[1], worst_curve, motor)
        row["band"]["stow_margin_worst_corner"] = worst_stow
        if plan.corner:
            row["band"]["simulation_worst_corner"] = _band_days(plan, candidate, current, results)
    row["governing"] = governing_case(plan, row)
    row["reasons"] = _reasons(plan, row, budget, day)
    unfinished = (row.get("band") or {}).get("simulation_worst_corner", {}).get("days_unfinished", [])
    if row["simulation"]["days_unfinished"]:
        row["verdict"] = "incomplete"
        row["reasons"].append(f"days not simulated (interrupted): {row['simulation']['days_unfinished']}")
    elif stow[0] is None and plan.scenario.wind.stow_speed is not None:  # an interrupted sizing draws no curve
        row["verdict"] = "incomplete"
        row["reasons"].append("stow margin not judged (interrupted: no speed-torque curve co-simulated)")
    elif unfinished:
        row["verdict"] = "incomplete"
        row["reasons"].append(f"days at the ranges' worst corner not simulated (interrupted): {unfinished}")
    else:
        row["verdict"] = "fail" if row["reasons"] else "pass"
    return row


#: The band's figures of the days co-simulated at the worst corner (:func:`_band_days`).
BAND_DAY_FIGURES = (
    "days_simulated",
    "days_unfinished",
    "days_failed",
    "steps_commanded",
    "missed_steps",
    "steps_lost",
    "max_tracking_error_deg",
    "drive_energy_per_day_J",
    "per_day",
)


def _band_days(plan: SizingPlan, candidate: MotorCandidate, current: float, results: Mapping[str, dict]) -> dict:
    """The days co-simulated again at the ranges' worst corner: their steps missed and lost, worst tracking
    error and energy, with the corner's values (shown beside the nominal days; not in the verdict)."""
    simulated = _simulated(plan, candidate, current, results, at_worst_corner=True)
    warnings = []  # what the sheet puts beside the verdict
    if simulated["steps_lost"] or simulated["missed_steps"]:
        warnings.append(
            f"at the ranges' worst corner {simulated['steps_lost']} steps lost and {simulated['missed_steps']} "
            f"missed in the days {simulated['days_simulated']}"
        )
    warnings += [f"at the ranges' worst corner day {day} failed: {error}" for day, error in simulated["days_failed"]]
    if simulated["days_unfinished"]:
        warnings.append(f"at the ranges' worst corner days not simulated (interrupted): {simulated['days_unfinished']}")
    return {
        "parameters": plan.corner,
        **{key: simulated[key] for key in BAND_DAY_FIGURES},
        "warnings": warnings,
    }


def _worst_corner_stow(
    plan: SizingPlan,
    candidate: MotorCandidate,
    current: float,
    angles: np.ndarray | None,
    curve: SpeedTorqueCurve | None,
    motor: str,
) -> float | None:
    """The stow margin [1] at the ranges' worst corner: that corner's drive (bus and loop gain), its step
    limit from rest and its co-simulated speed-torque curve; None without a stow or that curve."""
    varied = drive_at(candidate.drive(), worst_corner(plan.ranges), motor)
    sequencer = plan.scenario.sequencer
    limit = static_step_limit(varied, current, sequencer.mode, sequencer.microsteps)
    margin = stow_margin(plan, candidate, current, limit, curve, angles, varied)
    return None if margin is None else margin["stow_margin"]


def judge(
    plan: SizingPlan,
    results: Mapping[str, dict],
    curves: Mapping[str, SpeedTorqueCurve],
    worst_curves: Mapping[str, SpeedTorqueCurve] | None = None,
    angles: np.ndarray | None = None,
) -> dict:
    """The sheet: ``candidates`` (each with its currents' figures and verdicts), the smallest passing
    candidate and current, and why each smaller one fails; ``worst_curves``: each candidate's speed-torque
    curve at the ranges' worst corner (:func:`heliostep.sizing.band.worst_corner`); ``angles``: the
    panel angles a stow move travels [rad] (:func:`heliostep.sizing.stow.stow_angles`, found when
    not given): the stow margin is judged against each candidate's nominal curve."""
    if angles is None and curves:
        angles = stow_angles(plan)
    candidates, ordered = [], []
    for candidate in sorted(plan.candidates, key=lambda c: c.holding_torque):
        budgets = _budgets(plan, candidate)
        stow = (curves.get(candidate.name), angles)
        worst = worst_curves.get(candidate.name) if worst_curves else None
        rows = [
            _judge_current(plan, candidate, current, budgets, results, stow, worst) for current in candidate.currents
        ]
        passing = [row for row in rows if row["verdict"] == "pass"]
        entry = {
            **candidate.record(),
            "currents": rows,
            "verdict": "pass"
            if passing
            else ("incomplete" if any(r["verdict"] == "incomplete" for r in rows) else "fail"),
            "smallest_passing_current_A": passing[0]["current_A"] if passing else None,
        }
        if candidate.name in curves:
            entry["speed_torque"] = curves[candidate.name].record()
        if worst_curves and candidate.name in worst_curves:
            entry["speed_torque_worst"] = {
                **worst_curves[candidate.name].record(),
                "parameters": worst_corner(plan.ranges),
            }
        candidates.append(entry)
        ordered += [(candidate.name, row) for row in rows]
    first = next((k for k, (_, row) in enumerate(ordered) if row["verdict"] == "pass"), None)
    smaller = ordered if first is None else ordered[:first]
    return {
        "verdict": verdict_summary(plan, candidates, None if first is None else ordered[first][0]),
        "candidates": candidates,
        "smallest_passing": None
        if first is None
        else {"candidate": ordered[first][0], "current_A": ordered[first][1]["current_A"]},
        "smaller_ones_fail_because": [
            {"candidate": name, "current_A": row["current_A"], "verdict": row["verdict"], "reasons": row["reasons"]}
            for name, row in smaller
        ],
    }


#: The margins a verdict weighs, each in words: what the motor must do there.
MARGIN_CASES = {
    "tracking": "tracking: stepping from rest against the load at the worst instant",
    "idle": "idle: holding at idle current against the wind at the worst instant",
    "stow": "stowing: a stow move at the slew rate in the stow wind",
}


def governing_case(plan: SizingPlan, row: Mapping) -> dict:
    """The least of a candidate's margins at one current (tracking, idle, stow) and where it is: the day,
    the local time and the panel angle of the load budget's worst instant, or the stow move's angle."""
    margins = {"tracking": row["tracking_margin"], "idle": row["idle_margin"], "stow": row.get("stow_margin")}
    case, margin = min(((k, v) for k, v in margins.items() if v is not None), key=lambda item: item[1])
    record = {"case": case, "what": MARGIN_CASES[case], "margin": margin, "safety_factor": plan.safety_factor}
    if case == "stow":
        stow = row["stow_load"]
        return {**record, "panel_angle_deg": stow["panel_angle_deg"], "step_rate_per_s": stow["step_rate_per_s"]}
    budget = row["load_budget"]
    day = budget["day_of_year"]
    window = day_windows(plan.scenario)[day - 1]
    instant = None if window is None else window[0] + dt.timedelta(seconds=budget["time_s"])
    return {
        **record,
        "day_of_year": day,
        "date": date_of(plan.scenario.window.date.year, day).isoformat(),
        "local_time": None if instant is None else instant.isoformat(timespec="seconds"),
        "timezone": plan.scenario.site.timezone,
        "time_s": budget["time_s"],
        "panel_angle_deg": budget["panel_angle_deg"],
        "load_Nm": budget["total_Nm"],
    }


def verdict_summary(plan: SizingPlan, candidates: list[dict], chosen: str | None) -> dict:
    """The verdict in one paragraph's fields: the candidate and current chosen (None: none passes, then the
    largest candidate at its highest current stands in), its governing case, and why the next smaller
    candidate (at its highest current) fails; ``text``: the paragraph."""
    names = [c["name"] for c in candidates]
    if not candidates:
        return {"candidate": None, "current_A": None, "governing": None, "next_smaller": None, "text": ""}
    at = names.index(chosen) if chosen is not None else len(candidates) - 1
    entry = candidates[at]
    row = next((r for r in entry["currents"] if r["verdict"] == "pass"), entry["currents"][-1])
    smaller = candidates[at - 1] if at > 0 else None
    next_smaller = None
    if smaller is not None:
        best = smaller["currents"][-1]
        next_smaller = {
            "candidate": smaller["name"],
            "current_A": best["current_A"],
            "verdict": best["verdict"],
            "governing": best["governing"],
            "reasons": best["reasons"],
        }
    summary = {
        "candidate": entry["name"] if chosen is not None else None,
        "current_A": row["current_A"] if chosen is not None else None,
        "judged": {"candidate": entry["name"], "current_A": row["current_A"], "verdict": row["verdict"]},
        "governing": row["governing"],
        "next_smaller": next_smaller,
    }
    return {**summary, "text": _verdict_text(summary, row["reasons"])}


def _verdict_text(summary: Mapping, reasons: list[str]) -> str:
    """The verdict paragraph: chosen (or none), the governing case with its margin, the next smaller one."""
    judged, governing = summary["judged"], summary["governing"]
    pair = f"{judged['candidate']} at {judged['current_A']:g} A"
    if summary["candidate"] is not None:
        head = f"Chosen: {pair}."
    else:
        head = f"No candidate passes; the largest tried, {pair}, fails: {'; '.join(reasons)}."
    where = (
        f"at {governing['panel_angle_deg']:.1f} deg panel angle ({governing['step_rate_per_s']:.3g} full steps/s)"
        if governing["case"] == "stow"
        else f"on day {governing['day_of_year']} ({governing['date']}) at {(governing['local_time'] or '-')[11:19]} "
        f"{governing['timezone']}, {governing['time_s']:g} s into the window, panel at "
        f"{governing['panel_angle_deg']:.1f} deg"
    )
    body = (
        f" Governing case: {governing['what']}, {where}; margin {_margin(governing)} against the safety factor "
        f"{governing['safety_factor']:g}."
    )
    smaller = summary["next_smaller"]
    if smaller is None:
        tail = " No smaller candidate was tried."
    else:
        why = "; ".join(smaller["reasons"]) or "no reason recorded"
        fails = "fails" if smaller["verdict"] == "fail" else f"is {smaller['verdict']}"
        case = f"its governing case {smaller['governing']['case']}, margin {_margin(smaller['governing'])}"
        tail = (
            f" The next smaller candidate, {smaller['candidate']} at {smaller['current_A']:g} A ({case}), "
            f"{fails}: {why}."
        )
    return head + body + tail


def _margin(governing: Mapping) -> str:
    return "unbounded (no load)" if math.isinf(governing["margin"]) else f"{governing['margin']:.2f}"
