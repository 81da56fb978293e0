"""Tests of heliostep.results.light.sun_grid: a window's sun grid kept for the runs that share it, and
computed anew for any input it depends on that differs."""

from __future__ import annotations

from collections import OrderedDict

import numpy as np
import pandas as pd
import pytest

from heliostep.results.light import sun_grid as grids
from heliostep.results.light.on_tube import LightIntegrals
from heliostep.scenario import validate_scenario
from heliostep.solar.irradiance import WeatherFile
from weather_files import write_epw

PANEL_COLUMN = "mechanics.theta_p"
START = pd.Timestamp("2025-01-21 10:00", tz="Europe/Rome")
METADATA = {"window_start": START.isoformat(), "roles": {"panel_angle": PANEL_COLUMN}, "drive": {"step_times": []}}


def _scenario(distance=2.4, clouds=()):
    return validate_scenario(
        {
            "name": "sun-grid-test",
            "site": {"latitude": 40.0, "longitude": 14.25, "altitude": 0.0, "timezone": "Europe/Rome"},
            "window": {"date": "2025-01-21", "start": "10:00", "duration": 1800},
            "plant": {"orientation": "NS", "tube_height": 3.0},
            "mirror": {"distance": distance, "axis": "secondary"},
            **({"tracking": {"clouds": [dict(c) for c in clouds]}} if clouds else {}),
        }
    )


@pytest.fixture
def computed(monkeypatch):
    """The grids :func:`sun_grid` computes (their first point and count), none kept to begin with."""
    monkeypatch.setattr(grids, "_kept", OrderedDict())
    made = []
    original = grids.sun_grid

    def counting(grid_s, *args):
        made.append((float(grid_s[0]), len(grid_s)))
        return original(grid_s, *args)

    monkeypatch.setattr(grids, "sun_grid", counting)
    return made


def _figures(scenario, weather=None):
    seconds = np.arange(0.0, 1801.0, 10.0)
    angle = np.full(len(seconds), 0.1)
    trace = pd.DataFrame({"time": seconds, "panel_angle_ref": angle, PANEL_COLUMN: angle + 1e-4})
    integrals = LightIntegrals(METADATA, scenario, weather, first_order=False)
    integrals(trace)
    return integrals.figures()


def test_the_runs_of_one_window_share_its_sun_grid_computed_once(computed):
    scenario = _scenario()
    first = _figures(scenario)
    assert computed == [(0.0, 182)]  # 0 .. 1810 s every SUN_GRID_S (grid_span: a point past the end)
    assert _figures(_scenario()) == first  # a scenario equal to it, and its figures the same bit for bit
    assert computed == [(0.0, 182)]
    kept = grids.window_sun_grid(0.0, 1800.0, METADATA, scenario, None)
    fresh = grids.sun_grid(np.arange(182) * grids.SUN_GRID_S, METADATA, scenario, None)
    assert kept.keys() == fresh.keys()
    for key, values in kept.items():
        assert np.array_equal(values, fresh[key]), key
        assert not values.flags.writeable, key  # shared: no run may change it for the others
    with pytest.raises(ValueError, match="read-only"):
        kept["dni"][0] = 0.0


def test_a_grid_is_computed_anew_for_any_input_it_depends_on(computed):
    base = grids.window_sun_grid(0.0, 1800.0, METADATA, _scenario(), None)
    cloud = {"start": 600.0, "end": 900.0, "dni_fraction": 0.25}
    cloudy = grids.window_sun_grid(0.0, 1800.0, METADATA, _scenario(clouds=[cloud]), None)
    under = (base["time"] >= 600.0) & (base["time"] < 900.0)
    np.testing.assert_array_equal(cloudy["dni"], np.where(under, 0.25 * base["dni"], base["dni"]))
    other = grids.window_sun_grid(0.0, 1800.0, METADATA, _scenario(distance=-2.4), None)
    assert np.all(np.sign(other["ideal_primary"]) == -np.sign(base["ideal_primary"]))  # the mirror across the tube
    later = grids.window_sun_grid(
        0.0, 1800.0, {**METADATA, "window_start": "2025-01-21T11:00:00+01:00"}, _scenario(), None
    )
    assert np.all(later["elevation"] > base["elevation"])  # an hour nearer noon
    shorter = grids.window_sun_grid(10.0, 900.0, METADATA, _scenario(), None)
    np.testing.assert_array_equal(shorter["time"], np.arange(10.0, 911.0, 10.0))
    assert computed == [(0.0, 182)] * 4 + [(10.0, 91)]
    assert grids.window_sun_grid(10.0, 10.0, METADATA, _scenario(), None) is None  # the first row at the end


def test_the_last_kept_grids_are_kept(computed):
    for start in range(grids.KEPT_GRIDS + 1):
        grids.window_sun_grid(float(start), 60.0, METADATA, _scenario(), None)
    assert len(grids._kept) == grids.KEPT_GRIDS and len(computed) == grids.KEPT_GRIDS + 1
    grids.window_sun_grid(float(grids.KEPT_GRIDS), 60.0, METADATA, _scenario(), None)  # the last: kept
    assert len(computed) == grids.KEPT_GRIDS + 1
    grids.window_sun_grid(0.0, 60.0, METADATA, _scenario(), None)  # the first: dropped
    assert len(computed) == grids.KEPT_GRIDS + 2


def test_a_weather_file_s_path_is_read_each_time_and_a_file_read_keeps_its_own_grid(computed, tmp_path):
    # the EPW's hour 10 (the mean of 09:00-10:00) placed at 09:30, hour 11 at 10:30: DNI at 10:00 their mean
    path = tmp_path / "site.epw"
    scenario = _scenario()
    site = scenario.site.to_site()
    for rate in (40.0, 60.0):
        write_epw(path, latitude=40.0, longitude=14.25, dni_of_hour=lambda h, rate=rate: rate * h)
        grid = grids.window_sun_grid(0.0, 1800.0, METADATA, scenario, path)
        assert grid["dni"][0] == pytest.approx(10.5 * rate, rel=1e-12)  # the file as it is now
        read = WeatherFile.read(path, site)
        kept = grids.window_sun_grid(0.0, 1800.0, METADATA, scenario, read)
        assert kept["dni"][0] == pytest.approx(10.5 * rate, rel=1e-12)
        assert grids.window_sun_grid(0.0, 1800.0, METADATA, scenario, read) is kept
    assert len(computed) == 4 and len(grids._kept) == 2  # the paths' grids not kept, each file read its own
