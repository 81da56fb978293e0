"""The sizing's days at the worst corner of the drive physics' ranges (issue 23): beside the verdict, not in it.

Records given here for the nominal and the worst-corner cases of one candidate (no simulation: the
co-simulated ones are tests/cli/test_size.py's), judged: steps lost only at the corner leave the verdict on
the nominal figures and are named beside it, on the sheet and in its HTML.
"""

from __future__ import annotations

import numpy as np

from heliostep.paths import scenarios_dir
from heliostep.plots.sizing import sizing_html
from heliostep.run.speed_torque import SpeedTorqueCurve
from heliostep.scenario.catalogue import load_catalogue
from heliostep.sizing.size import plan_sizing
from heliostep.sizing.verdict import judge

SCENARIO = scenarios_dir() / "jan21-central.yaml"
NAME = "QSH8618-156-62-1280"  # the catalogue's strongest: its margins pass at a calm design gust


def _record(lost: int) -> dict:
    return {
        "complete": True,
        "steps_commanded": 4,
        "missed_steps": 0,
        "steps_lost": lost,
        "max_tracking_error_deg": 0.02,
        "electrical_energy_J": 100.0,
        "drive_energy_per_day_J": 1.0e6,
    }


def test_steps_lost_only_at_the_worst_corner_are_shown_beside_a_passing_verdict(fmu_paths):
    candidates = load_catalogue(None, [NAME])
    plan = plan_sizing(SCENARIO, candidates, design_gust=0.0, days=[21], overrides=["window.duration=60"])
    nominal = [case for case in plan.cases if not case.at_worst_corner]
    corner = [case for case in plan.cases if case.at_worst_corner]
    # every nominal case once more at the corner, after them, keyed apart
    assert [(c.candidate, c.current, c.day_of_year) for c in corner] == [
        (c.candidate, c.current, c.day_of_year) for c in nominal
    ]
    assert plan.cases == nominal + corner and all(c.key.endswith("/worst-corner") for c in corner)
    assert all("parameters.motor.K_current=18.1" in c.overrides for c in corner)
    results = {case.key: _record(0) for case in nominal} | {case.key: _record(3) for case in corner}
    curve = SpeedTorqueCurve(6.2, 8.9, np.array([5.0, 1000.0]), np.array([7.9, 2.1]))
    sheet = judge(plan, results, {NAME: curve})
    rows = sheet["candidates"][0]["currents"]
    for row in rows:
        assert row["verdict"] == "pass" and row["simulation"]["steps_lost"] == 0
        worst = row["band"]["simulation_worst_corner"]
        assert worst["steps_lost"] == 3 and worst["days_simulated"] == [21]
        assert worst["warnings"] == ["at the ranges' worst corner 3 steps lost and 0 missed in the days [21]"]
    page = sizing_html(
        {
            **sheet,
            "scenario": "s",
            "wind": {"moment_Nm": 0.0, "source": "x"},
            "safety_factor": 2.0,
            "days": [21],
            "complete": True,
        }
    )
    assert "Beside the verdict" in page and "3 steps lost" in page


def test_no_band_days_no_corner_cases(fmu_paths):
    candidates = load_catalogue(None, [NAME])
    plan = plan_sizing(
        SCENARIO, candidates, design_gust=0.0, days=[21], overrides=["window.duration=60"], band_days=False
    )
    assert plan.cases and not any(case.at_worst_corner for case in plan.cases)
    row = judge(plan, {case.key: _record(0) for case in plan.cases}, {})["candidates"][0]["currents"][0]
    assert "simulation_worst_corner" not in row["band"]


def test_a_sizing_stopped_in_the_corner_days_recommends_nothing(fmu_paths):
    """Stopped after every nominal day but before the corner's (the second half of the cases): no curve was
    co-simulated, so the stow margin is not judged, and the corner's days are missing: every pair is
    incomplete, none recommended, and the band does not read a clean 0 for days that never ran."""
    candidates = load_catalogue(None, [NAME])
    plan = plan_sizing(SCENARIO, candidates, design_gust=0.0, days=[21], overrides=["window.duration=60"])
    results = {case.key: _record(0) for case in plan.cases if not case.at_worst_corner}
    sheet = judge(plan, results, {}, {})  # what an interrupted sizing judges (no curves)
    assert sheet["smallest_passing"] is None
    for row in sheet["candidates"][0]["currents"]:
        assert row["verdict"] == "incomplete" and row["stow_margin"] is None
        assert any(reason.startswith("stow margin not judged") for reason in row["reasons"])
        worst = row["band"]["simulation_worst_corner"]
        assert worst["days_unfinished"] == [21] and worst["days_simulated"] == []
        assert worst["warnings"] == ["at the ranges' worst corner days not simulated (interrupted): [21]"]
    page = sizing_html(
        {**sheet, "scenario": "s", "wind": {"moment_Nm": 0.0, "source": "x"}, "safety_factor": 2.0, "days": [21]}
    )
    assert "days not simulated (interrupted): [21]" in page
    # without a stow the margins need no curve: the nominal days alone decide, the corner's still missing
    calm = plan_sizing(
        SCENARIO, candidates, design_gust=0.0, days=[21], overrides=["window.duration=60", "wind.stow_speed=null"]
    )
    done = {case.key: _record(0) for case in calm.cases if not case.at_worst_corner}
    row = judge(calm, done, {}, {})["candidates"][0]["currents"][0]
    assert row["verdict"] == "incomplete"
    assert row["reasons"] == ["days at the ranges' worst corner not simulated (interrupted): [21]"]


def test_a_motor_the_ranges_do_not_name_gets_no_corner_days(fmu_paths):
    """The ranges set parameters.motor.*: a scenario whose motor instance has another name would run the
    'worst corner' days with the rotor damping alone (already the mechanics' default), the nominal days
    again: none are planned."""
    candidates = load_catalogue(None, [NAME])
    roles = ("current_a_ref", "current_b_ref", "torque", "current_a", "current_b", "power")
    renamed = [
        "window.duration=60",
        "fmus.drive=StepperMotor",
        "fmus.motor=null",
        "connections=[[drive.tau, mechanics.tau], [mechanics.theta, drive.theta], [mechanics.omega, drive.omega]]",
        *(
            f"roles.{role}=drive.{name}"
            for role, name in zip(roles, ("i_a_ref", "i_b_ref", "tau", "i_a", "i_b", "power"))
        ),
        "roles.current_a_start=drive.i_a_start",
        "roles.current_b_start=drive.i_b_start",
    ]
    plan = plan_sizing(SCENARIO, candidates, design_gust=0.0, days=[21], overrides=renamed)
    assert plan.scenario.resolved_roles()["torque"] == "drive.tau"
    assert plan.cases and not any(case.at_worst_corner for case in plan.cases)
