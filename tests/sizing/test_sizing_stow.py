"""The margin to slip while stowing judged (issue 23): a stow move's load against a speed-torque curve given
here, no simulation (the co-simulated curve and the sheet's figures are tests/cli/test_size.py's)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from heliostep.paths import scenarios_dir
from heliostep.run.speed_torque import SpeedTorqueCurve
from heliostep.scenario.catalogue import load_catalogue
from heliostep.sizing.days import panel_angle_range
from heliostep.sizing.size import plan_sizing
from heliostep.sizing.verdict import judge

SCENARIO = scenarios_dir() / "jan21-central.yaml"
NAME = "QSH8618-65-59-340"  # currents 3, 4.5, 5.9 A


def _plan(stow_speed: str):
    candidates = load_catalogue(None, [NAME])
    overrides = ["window.duration=60", f"wind.stow_speed={stow_speed}"]
    return plan_sizing(SCENARIO, candidates, design_gust=0.0, days=[21], overrides=overrides)


def test_a_weak_curve_fails_the_stow_margin_and_the_sheet_names_it(fmu_paths):
    plan = _plan("40")
    # a curve far below the load: 0.05 N.m at 5 steps/s falling to 0.01 at 1000, at the largest current
    curve = SpeedTorqueCurve(5.9, 2.0, np.array([5.0, 1000.0]), np.array([0.05, 0.01]))
    sheet = judge(plan, {}, {NAME: curve})
    row = sheet["candidates"][0]["currents"][0]
    stow = row["stow_load"]
    assert row["current_A"] == 3.0
    # linear in the rate between the curve's points, scaled by the held current's ratio 3 / 5.9 (K I / (K + R))
    rate = stow["step_rate_per_s"]
    assert stow["pull_out_Nm"] == pytest.approx((0.05 - 0.04 * (rate - 5.0) / 995.0) * 3.0 / 5.9)
    assert row["stow_margin"] == pytest.approx(stow["deliverable_Nm"] / stow["total_Nm"])
    assert row["stow_margin"] < 2.0
    [reason] = [r for r in row["reasons"] if r.startswith("stow margin")]
    assert "40 m/s" in reason and "steps/s" in reason
    # the load at the reported angle: the flat plate's moment at 40 m/s x 1.52 (Hoerner's normal force at
    # Joessel's centre of pressure, the 0.3 m x 1.5 m mirror, ISA sea-level air), through g = s / (r cos^2)
    low, high = stow["angles_travelled_deg"]
    # from the stow angle (0) to the year's farthest tracking angle, not day 21's alone (29.7 deg in late
    # December against 27.3: tests/sizing/test_sizing_days.py::test_the_years_panel_angles_are_every_days_window)
    year = panel_angle_range(plan.scenario)
    assert (low, high) == pytest.approx((min(0.0, math.degrees(year[0])), math.degrees(year[1])))
    assert high > 27.5 + 2.0
    alpha = math.radians(abs(stow["panel_angle_deg"]))
    assert low <= stow["panel_angle_deg"] <= high and alpha > 0.0
    c_m = (0.5 - 0.195 - 0.305 * math.sin(alpha)) / (0.222 + 0.283 / math.sin(alpha))
    g = 0.3 / (2.5e-3 * math.cos(alpha) ** 2)
    assert stow["wind_Nm"] == pytest.approx(abs(c_m) * 0.5 * 1.225 * (1.52 * 40.0) ** 2 * 0.45 * 0.3 / g)
    assert stow["friction_Nm"] == pytest.approx(0.08 + 3.3e-3 / g)
    assert stow["deliverable_Nm"] == stow["pull_out_Nm"]  # far below the step limit from rest
    assert math.isfinite(row["stow_margin"])


def test_a_scenario_that_never_stows_has_no_stow_margin(fmu_paths):
    plan = _plan("null")
    curve = SpeedTorqueCurve(5.9, 2.0, np.array([5.0, 1000.0]), np.array([0.05, 0.01]))
    row = judge(plan, {}, {NAME: curve})["candidates"][0]["currents"][0]
    assert row["stow_margin"] is None and row["stow_load"] is None
    assert not any(r.startswith("stow margin") for r in row["reasons"])


def test_the_stow_margin_at_the_worst_corner_is_judged_on_that_corners_curve(fmu_paths):
    plan = _plan("40")
    assert plan.ranges  # the drive physics' ranges (data/parameter_ranges.yaml): the band is computed
    curve = SpeedTorqueCurve(5.9, 2.0, np.array([5.0, 1000.0]), np.array([0.05, 0.01]))
    # at the worst corner (lowest bus and loop gain) a curve half as strong: the load is the same (it
    # depends on the rotor's inertia and step angle, not on the bus or the loop gain), the held current's
    # ratio too (K I / (K + R) at 3 A over 5.9 A), and both curves stay below the step limit from rest, so
    # the margin there is half the nominal one
    worst = SpeedTorqueCurve(5.9, 2.0, np.array([5.0, 1000.0]), np.array([0.025, 0.005]))
    sheet = judge(plan, {}, {NAME: curve}, {NAME: worst})
    for row in sheet["candidates"][0]["currents"]:
        assert row["band"]["stow_margin_worst_corner"] == pytest.approx(row["stow_margin"] / 2.0, rel=1e-12)
    # without the worst corner's curve there is no such margin (and the nominal one stands)
    row = judge(plan, {}, {NAME: curve})["candidates"][0]["currents"][0]
    assert row["band"]["stow_margin_worst_corner"] is None and row["stow_margin"] is not None


def test_the_curve_scaled_to_a_lower_current_is_that_currents_own_at_a_stow_rate(fmu_paths):
    """The stow margin takes the curve co-simulated at the largest current, scaled to a lower one by the
    holding torques' ratio k_e K I / (K + R): at a stow move's step rate (tens of steps/s, the chopper keeps
    up) that is what the motor delivers at the lower current, co-simulated here at both currents."""
    from heliostep.run.speed_torque import speed_torque_curve

    [candidate] = load_catalogue(None, [NAME])
    drive, rate = candidate.drive(), 42.25  # a stow move's step rate: 0.5 deg/s through g at 27 deg
    high = speed_torque_curve(drive, 5.9, [rate], mode="one-phase-on", microsteps=1)
    low = speed_torque_curve(drive, 3.0, [rate], mode="one-phase-on", microsteps=1)
    scaled = high.at(rate) * drive.holding_torque(3.0) / drive.holding_torque(5.9)
    assert low.at(rate) == pytest.approx(scaled, rel=1e-3)  # measured: 1.00952 against 1.00951 N.m
    assert low.at(rate) < 0.6 * high.at(rate)  # and not trivially: the torque halves with the current
