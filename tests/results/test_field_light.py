"""Tests of heliostep.results.field_light and ``heliostep field-light``: every mirror's light on the tube per
day with the shared primary, against ray geometry written here (pvlib SPA and clear sky for the sun)."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pvlib
import pytest
from scipy.special import erf

from heliostep import cli
from heliostep.errors import InputError
from heliostep.paths import scenarios_dir
from heliostep.results.field_light import field_light_days
from heliostep.scenario import load_scenario

BASE = scenarios_dir() / "jan21-central.yaml"  # 40 N, 14.25 E, h = 3 m, 70 mm tube, mirrors 0.6 m apart
SUN_SIGMA = 4.65e-3 / 2  # [rad] pillbox sun of 4.65 mrad as its 1-D Gaussian sigma R/2 (Rabl 1985)
#: A point mirror of 1.5 m^2 with no slope error: its intercept is the sun's Gaussian on the tube (erf,
#: written below); the finite mirror's image is checked against a ray tracer (tests/solar/test_raytrace.py).
POINT = ("optics.mirror_width=1e-6", "optics.mirror_length=1e-6", "optics.mirror_area=1.5", "optics.slope_error=0")


def _sun(times):
    location = pvlib.location.Location(40.0, 14.25, "Europe/Rome", 0.0)
    sun = location.get_solarposition(times, method="nrel_numpy")
    a, z = np.radians(sun["apparent_elevation"].to_numpy()), np.radians(sun["azimuth"].to_numpy())
    dni = location.get_clearsky(times, model="ineichen")["dni"].fillna(0.0).clip(lower=0.0).to_numpy()
    return np.stack([np.cos(a) * np.sin(z), np.cos(a) * np.cos(z), np.sin(a)], axis=1), dni, a > 0


def _expected_day(scenario, day: int, distance: float, step_minutes: float = 10.0):
    """Energy on the tube of a mirror at ``distance`` for ideal tracking and with the shared primary [J]."""
    date = pd.Timestamp("2025-01-01") + pd.Timedelta(days=day - 1)
    start = date.tz_localize("Europe/Rome")
    times = pd.date_range(start, start + pd.Timedelta(days=1), freq=f"{step_minutes}min")
    s, dni, up = _sun(times)
    h, o = scenario.plant.tube_height, scenario.optics
    to_tube = np.array([-distance, 0.0, h]) / np.hypot(distance, h)

    def primary(sun, d):  # the primary angle of a two-axis mirror: its normal bisects sun and tube
        n = sun + np.array([-d, 0.0, h]) / np.hypot(d, h)
        return np.arctan2(n[..., 0], n[..., 2])

    noon = pvlib.solarposition.sun_rise_set_transit_spa(
        pd.DatetimeIndex([start + pd.Timedelta(hours=12)]), 40.0, 14.25
    )["transit"]
    s_noon = _sun(pd.DatetimeIndex(noon))[0][0]
    sharing = (primary(s, distance) - primary(s, 0.0)) - (primary(s_noon, distance) - primary(s_noon, 0.0))
    own = (s + to_tube) / np.linalg.norm(s + to_tube, axis=1)[:, None]
    c, si = np.cos(-sharing), np.sin(-sharing)  # the shared motor turns the own normal by -sharing about y
    shared = np.stack([own[:, 0] * c + own[:, 2] * si, own[:, 1], -own[:, 0] * si + own[:, 2] * c], axis=1)
    sigma = np.hypot(SUN_SIGMA, 2 * o.slope_error)
    chain = o.reflectivity * o.transmittance * o.absorptance
    seconds = (times - start).total_seconds().to_numpy()
    energies = []
    for n in (own, shared):
        cosine = np.sum(s * n, axis=1)
        ray = 2 * cosine[:, None] * n - s  # law of reflection
        across = np.hypot(ray[:, 0], ray[:, 2])
        miss = (-distance * ray[:, 2] - h * ray[:, 0]) / across
        slant = (-distance * ray[:, 0] + h * ray[:, 2]) / across**2 * np.linalg.norm(ray, axis=1)
        spread = np.sqrt(2) * slant * sigma
        half = o.tube_diameter / 2
        gamma = 0.5 * (erf((half - miss) / spread) + erf((half + miss) / spread))
        power = np.where(up, dni * o.aperture_area * np.clip(cosine, 0, None) * chain * gamma, 0.0)
        energies.append(np.trapezoid(power, seconds))
    return energies


@pytest.mark.filterwarnings("ignore::Warning")  # pvlib's own pandas deprecations
def test_field_light_per_day_and_mirror_against_ray_geometry():
    scenario = load_scenario(BASE, POINT)
    table = field_light_days(scenario, days=[21, 172], mirror_indices=[0, 6, 9, 12])
    assert len(table) == 8 and set(table["status"]) == {"ok"}
    rows = table.set_index(["day_of_year", "mirror_index"])
    for day in (21, 172):
        assert rows.loc[(day, 6), "light_lost_J"] == 0.0  # the central mirror's primary is the shared one
        # East and West outer mirrors lose alike over a day calibrated at its noon
        assert rows.loc[(day, 12), "light_lost_J"] == pytest.approx(rows.loc[(day, 0), "light_lost_J"], rel=0.01)
        for index, distance in ((9, 1.8), (12, 3.6)):
            ideal, shared = _expected_day(scenario, day, distance)
            assert rows.loc[(day, index), "mirror_distance_m"] == pytest.approx(distance)
            assert rows.loc[(day, index), "light_energy_ideal_J"] == pytest.approx(ideal, rel=1e-4)
            assert rows.loc[(day, index), "light_energy_J"] == pytest.approx(shared, rel=1e-3)
    assert rows.loc[(21, 12), "light_lost_fraction"] > rows.loc[(172, 12), "light_lost_fraction"] > 0.3


def test_bad_days_and_mirrors_are_errors():
    scenario = load_scenario(BASE)
    with pytest.raises(InputError, match="days"):
        field_light_days(scenario, days=[0])
    with pytest.raises(InputError, match="mirror"):
        field_light_days(scenario, days=[1], mirror_indices=[13])


def test_field_light_command_writes_the_table_and_heat_maps(tmp_path, capsys):
    out = tmp_path / "out"
    assert cli.main(["field-light", str(BASE), "--days", "21", "172", "--step-minutes", "20", "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "mirror  6 (d = +0.00 m)" in printed and "(  0.0 % lost)" in printed
    table = pd.read_csv(out / "field_light_days.csv")
    assert len(table) == 2 * 13
    for name in ("heatmap_light_lost_year.png", "heatmap_light_lost_fraction_year.png"):
        assert (out / name).read_bytes().startswith(b"\x89PNG")
