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
from heliostep.sweep.sizing import plan_sizing
from heliostep.sweep.sizing_verdict import judge

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
    assert all("parameters.motor.K_current=23.0" in c.overrides for c in corner)
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
