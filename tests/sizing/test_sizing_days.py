"""The days ``heliostep size`` co-simulates (issue 23): found over the year, each with its reason.

* the sun's fastest days against an independent calculation written here: pvlib's SPA sun, the central
  mirror's secondary angle from first principles (the normal bisects the sun and the vertical: n = (S + z)
  / |S + z|, q = -asin(n_y)), and its rate by central differences, over all 365 days;
* the windiest days against a year-long TMY3 file written here with known windy hours, one of them
  outside the tracking window (not chosen) and one whose ramp reaches the window only at its end (its
  window speed by linear interpolation, computed here);
* ``--days all`` and given days taken as they are.
"""

from __future__ import annotations

import datetime as dt
import math

import numpy as np
import pandas as pd
import pvlib
import pytest

from heliostep.errors import InputError
from heliostep.paths import scenarios_dir
from heliostep.scenario import load_scenario
from heliostep.sizing.days import PEAK_SEPARATION_DAYS, panel_angle_range, select_days

CENTRAL = scenarios_dir() / "jan21-central.yaml"  # 40 N, 14.25 E, Europe/Rome; 10:00 + 300 s; secondary, d = 0


def _secondary_rate(days: np.ndarray) -> np.ndarray:
    """The central mirror's largest |dq/dt| [deg/s] in 10:00 .. 10:05 local (Europe/Rome) of each day of
    2025: pvlib's SPA, n = (S + z) / |S + z|, q = -asin(n_y), central differences of +-1 s every 15 s."""
    centres, owner = [], []
    for day in days:
        date = dt.date(2025, 1, 1) + dt.timedelta(days=int(day) - 1)
        start = pd.Timestamp(dt.datetime.combine(date, dt.time(10, 0))).tz_localize("Europe/Rome")
        centres.append(start + pd.to_timedelta(np.arange(1.0, 300.0, 15.0), unit="s"))
        owner.append(np.full(len(centres[-1]), day))
    centre = centres[0].append(centres[1:])
    angles = []
    for shift in (-1.0, 1.0):
        sun = pvlib.solarposition.get_solarposition(
            centre + pd.Timedelta(seconds=shift), 40.0, 14.25, altitude=0.0, method="nrel_numpy"
        )
        elevation = np.radians(sun["apparent_elevation"].to_numpy())
        azimuth = np.radians(sun["azimuth"].to_numpy())  # NS plant: y to the north, x to the east
        s = np.stack([np.cos(elevation) * np.sin(azimuth), np.cos(elevation) * np.cos(azimuth), np.sin(elevation)])
        n = s + np.array([[0.0], [0.0], [1.0]])
        n /= np.linalg.norm(n, axis=0)
        angles.append(-np.arcsin(n[1]))
    rate = np.degrees(np.abs(angles[1] - angles[0]) / 2.0)
    out = pd.Series(rate).groupby(np.concatenate(owner)).max()
    return out.reindex(days).to_numpy()


def _secondary_angles(step: float) -> np.ndarray:
    """The central mirror's secondary angle q [rad] every ``step`` s over 10:00 .. 10:05 local of each day
    of 2025 (both ends included): pvlib's SPA, n = (S + z) / |S + z|, q = -asin(n_y)."""
    stamps = []
    for day in range(1, 366):
        date = dt.date(2025, 1, 1) + dt.timedelta(days=day - 1)
        start = pd.Timestamp(dt.datetime.combine(date, dt.time(10, 0))).tz_localize("Europe/Rome")
        stamps.append(start + pd.to_timedelta(np.arange(0.0, 300.0 + step / 2, step), unit="s"))
    sun = pvlib.solarposition.get_solarposition(stamps[0].append(stamps[1:]), 40.0, 14.25, method="nrel_numpy")
    elevation = np.radians(sun["apparent_elevation"].to_numpy())
    azimuth = np.radians(sun["azimuth"].to_numpy())
    s = np.stack([np.cos(elevation) * np.sin(azimuth), np.cos(elevation) * np.cos(azimuth), np.sin(elevation)])
    n = s + np.array([[0.0], [0.0], [1.0]])
    return -np.arcsin(n[1] / np.linalg.norm(n, axis=0))


def test_the_years_panel_angles_are_every_days_window():
    """The angles a stow may start from: the ideal secondary angle's least and largest over the year's
    windows (the sun always up at 10:00 at 40 N), against the independent angle on a 5 s grid."""
    angles = _secondary_angles(5.0)
    low, high = panel_angle_range(load_scenario(CENTRAL))
    assert low == pytest.approx(angles.min(), abs=1e-5) and high == pytest.approx(angles.max(), abs=1e-5)
    # wider than 21 January's window alone (27.3 .. 27.5 deg): a stow in late December starts 2.35 deg
    # farther from the stow angle (0 deg), at 29.85 deg, where g = s / (r cos^2) and the step rate are higher
    january = angles.reshape(365, -1)[20]
    assert high > january.max() + math.radians(2.0) and low < january.min()


def test_the_suns_fastest_days_are_found_over_the_year():
    selection = select_days(load_scenario(CENTRAL))
    days = np.arange(1, 366)
    expected = _secondary_rate(days)
    fastest = [day for day in selection.chosen if any(r.startswith("sun's fastest") for r in day.reasons)]
    assert [d.reasons[0].split(":")[0] for d in fastest if "#1" in d.reasons[0]] == ["sun's fastest #1"]
    first = next(d for d in fastest if "#1" in d.reasons[0])
    # the #1 day is the year's fastest (to the grids' difference), its rate the independent one
    assert expected[first.day_of_year - 1] >= expected.max() * (1 - 2e-3)
    for day in fastest:
        assert day.panel_rate_deg_s == pytest.approx(expected[day.day_of_year - 1], rel=2e-3)
        assert day.date == dt.date(2025, 1, 1) + dt.timedelta(days=day.day_of_year - 1)
    # a peak of the annual curve: nothing within PEAK_SEPARATION_DAYS is faster (to the grids' difference)
    for day in fastest:
        k = day.day_of_year - 1
        around = expected[[(k + j) % 365 for j in range(-PEAK_SEPARATION_DAYS, PEAK_SEPARATION_DAYS + 1)]]
        assert expected[k] >= around.max() * (1 - 2e-3)
    assert len(fastest) == 2 and abs(fastest[0].day_of_year - fastest[1].day_of_year) > PEAK_SEPARATION_DAYS
    assert "no weather file" in selection.criterion and selection.days == sorted(d.day_of_year for d in fastest)


WINDY = {40: (10, 15.0), 200: (10, 20.0), 250: (10, 9.0), 300: (11, 12.0), 100: (3, 40.0)}  # day: (hour, m/s)
CALM = 2.0  # [m/s] every other hour


def _year_tmy3(path) -> None:
    """A TMY3 file of a whole (non-leap) year, 1999, UTC+1, calm but for WINDY's hours, the wind from the south:
    normal to the central mirror's secondary axis (azimuth 90 deg), so its whole speed loads the panel."""
    lines = [
        "000000,'TEST',XX,1.0,40.0,14.25,0",
        "Date (MM/DD/YYYY),Time (HH:MM),GHI (W/m^2),DNI (W/m^2),DHI (W/m^2),Wdir (degrees),Wspd (m/s)",
    ]
    for day in range(1, 366):
        date = dt.date(1999, 1, 1) + dt.timedelta(days=day - 1)
        for hour in range(1, 25):
            when, speed = WINDY.get(day, (None, CALM))
            wind = speed if hour == when else CALM
            lines.append(f"{date:%m/%d/%Y},{hour:02d}:00,0,500,0,180,{wind}")
    path.write_text("\n".join(lines) + "\n")


def test_the_windiest_days_are_the_weather_files_within_the_window(tmp_path):
    _year_tmy3(tmp_path / "year.csv")
    overrides = ["site.timezone=Etc/GMT-1", "wind.weather_file=year.csv", "wind.stow_speed=null"]
    (tmp_path / "s.yaml").write_text(CENTRAL.read_text())
    selection = select_days(load_scenario(tmp_path / "s.yaml", overrides))
    windy = {d.day_of_year: d for d in selection.chosen if any(r.startswith("windiest") for r in d.reasons)}
    # 10:00-10:05 (UTC+1, the file's time): days 200, 40 and 250 have their gust at the window's start;
    # day 300's gust is at 11:00, so the window sees 2 + 10 x 5/60 m/s at its end; day 100's is at 03:00
    assert sorted(windy) == [40, 200, 250]
    assert [windy[d].wind_speed_m_s for d in (200, 40, 250)] == pytest.approx([20.0, 15.0, 9.0], rel=1e-9)
    assert windy[200].reasons[-1].startswith("windiest #1") and windy[250].reasons[-1].startswith("windiest #3")
    assert 100 not in selection.days and 300 not in selection.days
    assert "windiest days" in selection.criterion
    assert set(windy) < set(selection.days)  # the fastest days besides


def test_all_days_and_given_days_are_taken_as_they_are():
    scenario = load_scenario(CENTRAL)
    every = select_days(scenario, "all")
    assert every.days == list(range(1, 366)) and every.chosen[-1].date == dt.date(2025, 12, 31)
    given = select_days(scenario, [172, 21, 21])
    assert given.days == [21, 172] and given.chosen[0].reasons == ("given (--days)",)
    with pytest.raises(InputError, match="--days 'some'"):
        select_days(scenario, "some")


def _hinge_moment(speed: float, attack: float) -> float:
    """M = C_M 1/2 rho (G v)^2 A c of the flat mirror about its mid-chord: Hoerner's normal force
    C_N = 1 / (0.222 + 0.283 / sin a) at Joessel's centre of pressure x/c = 0.195 + 0.305 sin a; ISA
    sea-level air, Durst's gust factor 1.52, the 0.3 m x 1.5 m mirror (A = 0.45 m^2, c = 0.3 m)."""
    normal = 1.0 / (0.222 + 0.283 / math.sin(attack))
    arm = 0.5 - (0.195 + 0.305 * math.sin(attack))
    return normal * arm * 0.5 * 1.225 * (1.52 * speed) ** 2 * 0.45 * 0.3


def test_the_weather_files_wind_is_each_days_load_budget(tmp_path, fmu_paths):
    """Without a design gust the budget takes each day's wind over time: the windiest day's gust at the
    window's start is the worst instant, its moment the flat plate's, reflected through g."""
    from heliostep.scenario.catalogue import load_catalogue
    from heliostep.sizing.size import judge_candidates, plan_sizing

    _year_tmy3(tmp_path / "year.csv")
    (tmp_path / "s.yaml").write_text(CENTRAL.read_text())
    candidates = load_catalogue(None, ["QSH8618-80-55-460"])
    overrides = ["site.timezone=Etc/GMT-1", "wind.weather_file=year.csv", "wind.stow_speed=null"]
    plan = plan_sizing(tmp_path / "s.yaml", candidates, overrides=[*overrides, "window.duration=60"])
    assert plan.wind_moment is None and {40, 200, 250} < set(plan.days)
    assert all("wind.moment" not in item for case in plan.cases for item in case.overrides)
    sheet = judge_candidates(plan, {}, curves=False)  # the budgets need no simulation
    budget = sheet["candidates"][0]["currents"][0]["load_budget"]
    assert budget["day_of_year"] == 200 and budget["time_s"] < 1.0  # 20 m/s at 10:00, the window's start
    attack = math.radians(abs(budget["panel_angle_deg"]))
    assert abs(budget["wind_moment_Nm"]) == pytest.approx(_hinge_moment(20.0, attack), rel=1e-2)
    # g = s / (r cos^2 theta_p), the paper's lever 0.3 m and pinion 2.5 mm
    assert budget["wind_Nm"] == pytest.approx(
        abs(budget["wind_moment_Nm"]) * 2.5e-3 * math.cos(attack) ** 2 / 0.3, rel=1e-9
    )


def test_with_a_weather_file_only_the_days_it_covers_are_taken(tmp_path):
    from weather_files import write_epw

    write_epw(tmp_path / "w.epw", latitude=40.0, longitude=14.25, wind_of_hour=lambda h: 3.0 + h)  # 21 January
    (tmp_path / "s.yaml").write_text(CENTRAL.read_text())
    scenario = load_scenario(tmp_path / "s.yaml", ["wind.weather_file=w.epw"])
    selection = select_days(scenario)
    # the one day the file covers is both the fastest and the windiest there: 3 + 10 m/s at 10:00, 3 + 11 at
    # 11:00, so 13 + 5/60 m/s at the window's end (10:05)
    assert selection.days == [21]
    assert selection.chosen[0].wind_speed_m_s == pytest.approx(13.0 + 5.0 / 60.0)
    with pytest.raises(InputError, match=r"w\.epw has no wind speed within the window on day\(s\) \[172\]"):
        select_days(scenario, [21, 172])


def test_the_years_windows_are_kept_per_window_and_site():
    """day_windows keeps the 365 windows of a (window, site) pair: asked again, the same; another site or
    window, its own (a sunrise-to-sunset window's 365 SPA searches take seconds)."""
    from heliostep.sizing.days import _year_windows, day_windows

    scenario = load_scenario(CENTRAL)
    assert day_windows(scenario) == day_windows(scenario) == _year_windows(scenario)
    # the same clock times in a zone without summer time: from the last Sunday of March an hour apart
    standard = load_scenario(CENTRAL, ["site.timezone=Etc/GMT-1"])
    rome, gmt1 = day_windows(scenario), day_windows(standard)
    assert rome[0][0] == gmt1[0][0] and (gmt1[171][0] - rome[171][0]).total_seconds() == 3600.0
    later = load_scenario(CENTRAL, ["window.start=11:00"])
    assert (day_windows(later)[0][0] - rome[0][0]).total_seconds() == 3600.0
