"""Wind over time and stow, co-simulated: scenarios/jan21-windy.yaml (a design gust above the stow speed).

The stow and return moves are stepped and co-simulated; the tests check the steps against the angle
the panel travelled (steps x increment = the rotor's travel = (s/r) (tan theta_1 - tan theta_0),
[paper] eq. 14), the held stow angle, the return after the calm time computed here from the gust's
points, and the moment fed to the mechanics against the formula written here. Bad wind input: exit 2
naming the file and key, before simulating.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from heliostep import cli
from heliostep.paths import scenarios_dir
from heliostep.run import run_scenario
from weather_files import write_epw

SCENARIO = scenarios_dir() / "jan21-windy.yaml"
R, S = 2.5e-3, 0.3  # the paper's Table 2 pinion radius and lever arm [m]
INCREMENT = math.radians(1.8)  # one-phase-on full steps
# the gust: 5 m/s, up to 18 m/s over 20-30 s, down to 5 m/s over 60-70 s; threshold 12 m/s, calm 60 s
STOW_AT = 20.0 + 10.0 * (12.0 - 5.0) / 13.0
CALM_FROM = 60.0 + 10.0 * (18.0 - 12.0) / 13.0
RETURN_AT = CALM_FROM + 60.0


@pytest.fixture(scope="module")
def windy_run(fmu_paths):
    return run_scenario(SCENARIO)


def _panel_at(trace, t):
    """The panel angle [rad] at the last row at or before ``t``."""
    rows = trace[trace["time"] <= t]
    return float(rows["mechanics.theta_p"].iloc[-1])


def test_stow_starts_above_the_threshold_and_returns_after_the_calm_time(windy_run):
    stow, back = windy_run.summary["stow_moves"]
    assert (stow["kind"], back["kind"]) == ("stow", "return")
    assert stow["start_s"] == pytest.approx(STOW_AT, abs=1e-9)
    assert back["start_s"] == pytest.approx(RETURN_AT, abs=1e-9)
    steps = windy_run.inputs.schedule.times
    assert not np.any((steps > stow["end_s"]) & (steps < back["start_s"]))  # nothing commanded while held


@pytest.mark.parametrize("move", [0, 1])
def test_steps_of_a_move_equal_the_angle_travelled(windy_run, move):
    record = windy_run.summary["stow_moves"][move]
    trace = windy_run.trace
    start, end = record["start_s"], record["end_s"] + 0.05
    before, after = _panel_at(trace, start - 1e-6), _panel_at(trace, end)
    rotor_travel = S / R * (math.tan(after) - math.tan(before))  # [paper], eq. 14
    # the steps the run commanded over the move, and those the rotor made, against the travel
    assert record["steps_commanded"] == pytest.approx(abs(rotor_travel) / INCREMENT, abs=1.0)
    rotor = trace["mechanics.theta"].to_numpy()
    time = trace["time"].to_numpy()
    made = (rotor[time <= end][-1] - rotor[time < start][-1]) / INCREMENT
    assert abs(made) == pytest.approx(record["steps_commanded"], abs=0.5)
    assert record["missed_steps"] == 0 and record["steps_lost"] == 0
    assert 0.0 < record["peak_torque_Nm"] <= 2.75 * 1.1  # k_e I = 2.75 N.m holding torque class
    # the slew rate: 0.5 deg/s on the panel (the scenario's default)
    assert abs(math.degrees(after - before)) / (record["end_s"] - record["start_s"]) == pytest.approx(0.5, rel=0.01)


def test_stow_angle_is_held(windy_run):
    stow, back = windy_run.summary["stow_moves"]
    trace = windy_run.trace
    held = trace[(trace["time"] > stow["end_s"] + 0.5) & (trace["time"] < back["start_s"])]
    # flat within the elastic lag of a detent: far under a tenth of a degree
    assert np.max(np.abs(held["mechanics.theta_p"])) < math.radians(0.01)
    assert len(held) > 100


def test_moment_fed_to_the_mechanics_is_the_formula_on_the_commanded_angle(windy_run):
    trace = windy_run.trace
    rows = trace[(trace["time"] > 1.0) & (trace["time"] < 19.0)]  # constant 5 m/s, tracking
    panel0 = float(trace["panel_angle_ref"].iloc[0])
    commanded = np.arctan(np.tan(panel0) + rows["rotor_angle_cmd"].to_numpy() * R / S)  # [paper], eq. 14
    alpha = np.abs(commanded)
    normal = 1.0 / (0.222 + 0.283 / np.sin(alpha))  # Hoerner
    cm = normal * (0.5 - (0.195 + 0.305 * np.sin(alpha)))  # Joessel's centre of pressure
    q = 0.5 * (101325.0 / (287.05287 * 288.15)) * 5.0**2  # ISA sea level, gust factor 1
    expected = -np.sign(commanded) * cm * q * (0.3 * 1.5) * 0.3  # m_ext = -M, the Table 2 panel
    assert rows["m_ext"].to_numpy() == pytest.approx(expected, rel=1e-9)
    held = trace[(trace["time"] > 45.0) & (trace["time"] < 120.0)]
    # held flat: the commanded angle is the detent nearest 0, within half a panel step (0.0075 deg),
    # where C_M is 3.5 alpha x 0.305 = 1.4e-4 at most: under 1 mN.m at 18 m/s
    flat = np.arctan(np.tan(panel0) + held["rotor_angle_cmd"].to_numpy() * R / S)
    assert np.max(np.abs(flat)) < math.radians(0.0076)
    assert np.max(np.abs(held["m_ext"])) < 1e-2 < np.min(np.abs(rows["m_ext"]))


def test_light_lost_while_stowed_is_counted(windy_run):
    summary = windy_run.summary
    assert summary["stowed_time_s"] == pytest.approx(summary["stow_moves"][1]["end_s"] - STOW_AT)
    assert summary["stowed_share"] == pytest.approx(summary["stowed_time_s"] / 150.0)
    assert 0.0 < summary["light_lost_stowed_J"] <= summary["light_energy_ideal_J"]
    assert summary["light_lost_stowed_share"] == pytest.approx(
        summary["light_lost_stowed_J"] / summary["light_energy_ideal_J"]
    )


def test_idle_holding_margin_is_the_wind_at_its_worst_instant(windy_run):
    summary = windy_run.summary
    worst = windy_run.metadata["drive"]["wind"]
    assert summary["wind_moment_Nm"] == worst["moment_Nm"] != 0.0
    # the holding moment at that instant over the wind's: g = s / (r cos^2) at the commanded angle there
    assert summary["idle_holding_margin"] == pytest.approx(
        worst["drive_ratio"] * summary["holding_torque_idle_Nm"] / abs(worst["moment_Nm"])
    )
    assert abs(worst["moment_Nm"]) == pytest.approx(summary["wind_peak_moment_Nm"], rel=0.2)


def _run(tmp_path, capsys, *overrides):
    argv = ["run", str(SCENARIO), "--out", str(tmp_path / "out"), "--no-plots"]
    for item in overrides:
        argv += ["--set", item]
    status = cli.main(argv)
    return status, capsys.readouterr().err


def test_a_stow_speed_below_zero_is_exit_2_naming_the_key(tmp_path, capsys):
    status, err = _run(tmp_path, capsys, "wind.stow_speed=-1")
    assert status == 2 and SCENARIO.name in err and "wind.stow_speed" in err
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize(
    "overrides, key",
    [
        (["wind.profile=null", "wind.speed=-2"], "wind.speed"),
        (["wind.speed=8"], "wind.profile"),  # a second source beside the profile: "got speed, profile"
        (["wind.moment=5"], "wind.moment"),  # a constant moment and a speed
        (["wind.profile=[[0, 5], [0, 6]]"], "wind.profile"),
        (["wind.profile=[[0, 5], [10, -1]]"], "wind.profile"),
        (["wind.slew_rate=0"], "wind.slew_rate"),
        (["wind.calm_time=-1"], "wind.calm_time"),
    ],
)
def test_bad_wind_keys_are_exit_2_naming_the_key(tmp_path, capsys, overrides, key):
    status, err = _run(tmp_path, capsys, *overrides)
    assert status == 2 and SCENARIO.name in err and key in err
    assert not (tmp_path / "out").exists()


def test_a_weather_file_without_wind_speed_is_exit_2_naming_the_file_and_key(tmp_path, capsys):
    path = write_epw(tmp_path / "calm.epw", latitude=40.0, longitude=14.25, wind_of_hour=lambda h: 999.0)  # missing
    status, err = _run(tmp_path, capsys, "wind.profile=null", f"wind.weather_file={path}")
    assert status == 2
    assert SCENARIO.name in err and "wind.weather_file" in err and str(path) in err and "wind speed" in err
    assert not (tmp_path / "out" / "trace.parquet").exists()


def test_a_weather_files_wind_speed_is_the_load(tmp_path, capsys, fmu_paths):
    # 14 m/s at 11:00, 15 m/s at 12:00 (EPW hours ending then; the wind measured at the stamp)
    path = write_epw(tmp_path / "windy.epw", latitude=40.0, longitude=14.25, wind_of_hour=lambda h: 3.0 + h)
    status, _ = _run(
        tmp_path,
        capsys,
        "wind.profile=null",
        f"wind.weather_file={path}",
        'window.start="11:15"',
        "window.duration=20",
        "wind.stow_speed=null",
        "wind.gust_factor=1.52",
    )
    assert status == 0
    metadata = json.loads((tmp_path / "out" / "metadata.json").read_text())
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert "stow_moves" not in metadata["drive"] or metadata["drive"]["stow_moves"] == []
    assert summary["stow_moves"] == []
    # the largest moment over the window: at its end (the speed rises), on the commanded angle there
    # (the final panel angle is within the tracking error, < 0.1 deg: C_M within 1 %)
    speed = 14.0 + 1.0 * (15.0 * 60 + 20.0) / 3600.0
    panel = math.radians(summary["final_panel_angle_deg"])
    alpha = abs(panel)
    cm = (1.0 / (0.222 + 0.283 / math.sin(alpha))) * (0.5 - 0.195 - 0.305 * math.sin(alpha))
    density = 101325.0 / (287.05287 * (273.15 + 10.0))  # sea level at the file's dry bulb, 10 degC
    expected = cm * 0.5 * density * (1.52 * speed) ** 2 * 0.45 * 0.3
    assert summary["wind_peak_moment_Nm"] == pytest.approx(expected, rel=0.01)
