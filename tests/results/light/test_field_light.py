"""Tests of heliostep.results.light.field and ``heliostep field-light``: every mirror's light on the tube per
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
from heliostep.results.light.field import field_light_days
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
    from mirror_tracer import receiver_hit

    # the point mirror is wholly in the tube's shadow when its sun ray passes within D/2 of the tube's axis
    lit = ~receiver_hit(np.tile([distance, 0.0, 0.0], (len(s), 1)), s, h, o.tube_diameter / 2)
    for n in (own, shared):
        cosine = np.sum(s * n, axis=1) * lit
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
    # the point mirror has no area to shade: shading and blocking have their own tests below
    table = field_light_days(scenario, days=[21, 172], mirror_indices=[0, 6, 9, 12], shading=False)
    assert len(table) == 8 and set(table["status"]) == {"ok"}
    rows = table.set_index(["day_of_year", "mirror_index"])
    for day in (21, 172):
        assert rows.loc[(day, 6), "light_lost_J"] == 0.0  # the central mirror's primary is the shared one
        # East and West outer mirrors lose alike over a day calibrated at its noon (to 5 %: the point mirror is
        # wholly in the tube's shadow or not, for a few minutes that the 10-min grid samples unevenly)
        assert rows.loc[(day, 12), "light_lost_J"] == pytest.approx(rows.loc[(day, 0), "light_lost_J"], rel=0.05)
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
    central = next(line for line in printed.splitlines() if "mirror  6 (d = +0.00 m)" in line)
    # its own primary is the shared one; only its neighbours' shared primaries change the shade on it
    assert abs(float(central.split("(")[2].split("%")[0])) <= 0.2 and "shading and blocking" in central
    assert "the field" in printed
    table = pd.read_csv(out / "field_light_days.csv")
    assert len(table) == 2 * 13
    for name in ("heatmap_light_lost_year.png", "heatmap_light_lost_fraction_year.png"):
        assert (out / name).read_bytes().startswith(b"\x89PNG")
    bare = ["--no-shading", "--no-plots", "--out", str(tmp_path / "bare")]
    assert cli.main(["field-light", str(BASE), "--days", "21", "--step-minutes", "20", *bare]) == 0
    assert "mirror  6 (d = +0.00 m)" in (printed := capsys.readouterr().out) and "(  0.0 % lost)" in printed


# --------------------------------------------------------------------------- shading and blocking in the field
FIELD_H, FIELD_W, FIELD_L, FIELD_SPACING = 3.0, 0.3, 1.5, 0.6  # jan21-central: Table 2's panel, h = 3 m
FIELD_INSTANTS = ["2025-01-21 09:00", "2025-01-21 12:14", "2025-06-21 16:00"]


def _field_normals(times):
    """The sun [-] (T, 3) and the field's normals [-] (T, 13, 3) at ``times`` (one day): ideal (the bisector
    of sun and tube) and with the primary shared with the central mirror, exact at that day's solar noon
    (the same geometry as _expected_day, written here)."""
    from mirror_tracer import tracking_normals

    distances = (np.arange(13) - 6) * FIELD_SPACING
    sun = _sun(times)[0]
    ideal = tracking_normals(sun, distances, FIELD_H, two_axis=True)
    day = times[0].normalize()
    noon = pvlib.solarposition.sun_rise_set_transit_spa(pd.DatetimeIndex([day + pd.Timedelta(hours=12)]), 40.0, 14.25)
    s_noon = _sun(pd.DatetimeIndex(noon["transit"]))[0][0]

    def primary(s, d):  # the normal bisects sun and tube: its angle about y
        n = s + np.array([-d, 0.0, FIELD_H]) / np.hypot(d, FIELD_H)
        return np.arctan2(n[..., 0], n[..., 2])

    err = np.stack(
        [(primary(sun, d) - primary(sun, 0.0)) - (primary(s_noon, d) - primary(s_noon, 0.0)) for d in distances], 1
    )
    c, si = np.cos(-err), np.sin(-err)  # the shared motor turns the own normal by -err about y
    shared = np.stack(
        [ideal[..., 0] * c + ideal[..., 2] * si, ideal[..., 1], -ideal[..., 0] * si + ideal[..., 2] * c], axis=-1
    )
    return sun, ideal, shared


@pytest.mark.filterwarnings("ignore::Warning")  # pvlib's own pandas deprecations
def test_field_shading_and_blocking_match_the_ray_tracer():
    # Every field mirror's unhidden share, ideal and with the shared primary (the neighbours share it too),
    # against the ray tracer (tests/support/mirror_tracer.py: 40 000 points, standard error <= 0.0025) on a section of
    # 7 contiguous mirrors along each of the 13 rows; the band: tests/solar/test_shading.py's two-axis one
    from heliostep.results.light.field import field_light_instants
    from mirror_tracer import layout, trace

    scenario = load_scenario(BASE)
    assert (scenario.optics.mirror_width, scenario.optics.mirror_length) == (FIELD_W, FIELD_L)
    rng = np.random.default_rng(20)
    distances, grid, ys = layout(FIELD_SPACING, along=FIELD_L, n_along=7)
    for stamp in FIELD_INSTANTS:
        when = pd.DatetimeIndex([pd.Timestamp(stamp, tz="Europe/Rome")])
        sun, ideal, shared = _field_normals(when)
        light = field_light_instants(scenario, when, when[0].date())
        if stamp.endswith("12:14"):  # solar noon: the tube's shadow lies on the central mirror
            assert light["unhidden_ideal"][0, 6] < 1 - 0.07 / 0.3 + 0.05
        for key, normals, rows in (("shared", shared, (0, 3, 6, 9, 12)), ("ideal", ideal, (0, 6))):
            for i in rows:
                target = (len(ys) // 2) * 13 + i
                tiled = np.tile(normals[0], (len(ys), 1))
                lost = trace(sun[0], tiled, grid, target, FIELD_W, FIELD_L, FIELD_H, rng, receiver_radius=0.035)[2]
                assert light[f"unhidden_{key}"][0, i] == pytest.approx(1.0 - lost, abs=0.02), (stamp, key, i)
                power = light[f"power_{key}_unshaded_W"][0, i] * (1.0 - lost)
                assert light[f"power_{key}_W"][0, i] == pytest.approx(power, rel=0.03, abs=1.0)


@pytest.mark.filterwarnings("ignore::Warning")
def test_the_field_never_collects_more_than_the_beam_its_aperture_sees():
    # At every 30 min of the 21st of each month, the 13 mirrors' collected beam per pitch along the row,
    # DNI sum_i cos_i (1 - lost_i) w l, is at most the beam entering the slab bounding their corners:
    # through its top (S_z x its width) and its sun-facing side (|S_x| x its height), l along the row
    from heliostep.results.light.field import field_light_instants
    from mirror_tracer import rectangle

    scenario = load_scenario(BASE)
    distances = (np.arange(13) - 6) * FIELD_SPACING
    checked, worst_bare = 0, 0.0
    for month in range(1, 13):
        day = pd.Timestamp(f"2025-{month:02d}-21", tz="Europe/Rome")
        times = pd.date_range(day + pd.Timedelta(hours=5), day + pd.Timedelta(hours=20), freq="30min")
        light = field_light_instants(scenario, times, day.date())
        s, ideal, shared = _field_normals(times)
        for key, normals in (("ideal", ideal), ("shared", shared)):
            collected = np.sum(light[f"cosine_{key}"] * light[f"unhidden_{key}"], axis=1) * FIELD_W * FIELD_L
            bare = np.sum(np.clip(light[f"cosine_{key}"], 0, None), axis=1) * FIELD_W * FIELD_L
            for t in np.flatnonzero(s[:, 2] > np.sin(np.radians(1.0))):
                corners = np.array(
                    [
                        [d, 0, 0] + f[:, 0] * su * FIELD_W / 2 + f[:, 1] * sv * FIELD_L / 2
                        for d, f in zip(distances, (rectangle(n) for n in normals[t]))
                        for su in (-1, 1)
                        for sv in (-1, 1)
                    ]
                )
                span = corners.max(axis=0) - corners.min(axis=0)
                aperture = (s[t, 2] * span[0] + abs(s[t, 0]) * span[2]) * FIELD_L
                assert collected[t] <= aperture * (1 + 1e-9), (month, times[t], key)
                worst_bare = max(worst_bare, bare[t] / aperture)
                checked += 1
            assert np.all(collected <= bare + 1e-12)
    assert checked > 300
    assert worst_bare > 2, worst_bare  # without shading and blocking it would be broken (5.6x at low sun)


@pytest.mark.filterwarnings("ignore::Warning")
def test_shading_every_30_min_interpolated_moves_a_day_by_less_than_0_3_percent():
    # the default (shading and blocking every 30 min, linear between) against every 10-min instant, on the
    # solstices and 21 January: the field's day within 0.3 %, each mirror's within 0.5 %
    scenario = load_scenario(BASE)
    coarse, fine = (field_light_days(scenario, days=[21, 172, 355], shading_step_minutes=m) for m in (30.0, 10.0))
    for column in ("light_energy_ideal_J", "light_energy_J"):
        by_day = [table.groupby("day_of_year")[column].sum() for table in (coarse, fine)]
        assert np.allclose(by_day[0], by_day[1], rtol=0.003, atol=0), column
        assert np.allclose(coarse[column], fine[column], rtol=0.005, atol=0), column
    assert not np.allclose(coarse["light_energy_ideal_J"], fine["light_energy_ideal_J"], rtol=1e-9, atol=0)
