"""Tests of heliostep.solar against published values and first principles.

Reference values live in named fixtures with their source; none is copied from
this module's own output.
"""

from __future__ import annotations

import datetime as dt
import subprocess
import sys

import numpy as np
import pandas as pd
import pytest

from heliostep import solar as geometry
from heliostep.errors import InputError

OBLIQUITY_DEG = 23.44  # Earth's axial tilt: the sun's declination at the solstices


# --------------------------------------------------------------------------- fixtures
@pytest.fixture
def spa_reference_example():
    """Reda & Andreas, NREL/TP-560-34302 (2004, rev. 2008), Table A5.1: the SPA example."""
    return {
        "time": pd.Timestamp("2003-10-17 12:30:30", tz=dt.timezone(dt.timedelta(hours=-7))),
        "latitude": 39.742476,
        "longitude": -105.1786,
        "altitude": 1830.14,  # [m]
        "pressure": 82000.0,  # [Pa] (820 mbar)
        "temperature": 11.0,  # [degC]
        "delta_t": 67.0,  # [s]
        "topocentric_zenith": 50.11162,  # [deg], refraction-corrected
        "topocentric_azimuth": 194.34024,  # [deg], from North toward East
    }


@pytest.fixture
def paper_fig2_site():
    """The paper's Fig. 2: NS plant at 40 deg N, h = 5 m, central mirror d = 0.

    Longitude 14.25 E and Europe/Rome are our assumption (the paper gives only the
    latitude); the end loss depends on the sun's altitude and azimuth, not on them.
    """
    return {
        "site": geometry.Site(latitude=40.0, longitude=14.25, timezone="Europe/Rome"),
        "tube_height": 5.0,
        "mirror_distance": 0.0,
    }


@pytest.fixture
def paper_transmission():
    """The paper's secondary drive, eqs. 12-15: pinion radius r = 2.5 mm, lever arm s = 0.3 m."""
    return {"pinion_radius": 2.5e-3, "lever_arm": 0.3}


@pytest.fixture
def rng():
    return np.random.default_rng(20240521)


def _day(site, date, freq="1min"):
    start = pd.Timestamp(date).tz_localize(site.timezone)
    return pd.date_range(start, start + pd.Timedelta(days=1), freq=freq, inclusive="left")


def _random_sun(rng, n):
    """Unit vectors uniformly spread over the upper hemisphere (sun above the horizon)."""
    vectors = rng.normal(size=(n, 3))
    vectors[:, 2] = np.abs(vectors[:, 2]) + 1e-3
    return vectors / np.linalg.norm(vectors, axis=1, keepdims=True)


def _angle_between(a, b):
    """Angle between rows of a and b [rad], stable for tiny angles."""
    cross = np.linalg.norm(np.cross(a, b), axis=-1)
    dot = np.sum(a * b, axis=-1)
    return np.arctan2(cross, dot)


def _rotation_y(angle):
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def _rotation_x(angle):
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


# --------------------------------------------------------------------------- sun position
def test_solar_position_matches_spa_published_example(spa_reference_example):
    ref = spa_reference_example
    position = geometry.solar_position(
        pd.DatetimeIndex([ref["time"]]),
        ref["latitude"],
        ref["longitude"],
        ref["altitude"],
        pressure=ref["pressure"],
        temperature=ref["temperature"],
        delta_t=ref["delta_t"],
    )
    assert {"elevation", "apparent_elevation", "azimuth"} <= set(position.columns)
    assert 90.0 - position["apparent_elevation"].iloc[0] == pytest.approx(ref["topocentric_zenith"], abs=1e-4)
    assert position["azimuth"].iloc[0] == pytest.approx(ref["topocentric_azimuth"], abs=1e-4)


def test_sun_vector_components_and_series_in_series_out():
    index = pd.date_range("2025-01-01", periods=4, freq="h", tz="UTC")
    elevation = pd.Series([0.0, 30.0, 60.0, 90.0], index=index)
    azimuth = pd.Series([90.0, 180.0, 270.0, 0.0], index=index)
    sun_x, sun_y, sun_z = geometry.sun_vector(elevation, azimuth)
    for component in (sun_x, sun_y, sun_z):
        assert isinstance(component, pd.Series)
        assert component.index.equals(index)
    np.testing.assert_allclose(sun_x**2 + sun_y**2 + sun_z**2, 1.0, atol=1e-15)
    # due East on the horizon: +x; due South at 30 deg: -y; due West at 60 deg: -x
    np.testing.assert_allclose([sun_x.iloc[0], sun_y.iloc[0], sun_z.iloc[0]], [1.0, 0.0, 0.0], atol=1e-15)
    np.testing.assert_allclose(
        [sun_x.iloc[1], sun_y.iloc[1], sun_z.iloc[1]], [0.0, -np.cos(np.pi / 6), 0.5], atol=1e-15
    )
    np.testing.assert_allclose(sun_x.iloc[2], -0.5, atol=1e-15)


def test_east_west_plant_is_the_frame_turned_by_90_degrees():
    plant = geometry.Plant(tube_height=5.0, orientation="EW")
    assert plant.azimuth == 90.0
    assert geometry.Plant(tube_height=5.0, orientation="ns", azimuth_offset=10.0).azimuth == 10.0
    # EW plant: +y = East, +x = South, z up (right-handed: South x East = Up)
    elevation = np.array([0.0, 0.0, 0.0])
    azimuth = np.array([90.0, 180.0, 0.0])  # East, South, North on the horizon
    sun = np.column_stack(geometry.sun_vector(elevation, azimuth, plant.azimuth))
    np.testing.assert_allclose(sun, [[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [-1.0, 0.0, 0.0]], atol=1e-15)
    np.testing.assert_allclose(np.cross(sun[1], sun[0]), [0.0, 0.0, 1.0], atol=1e-15)


# --------------------------------------------------------------------------- end loss, eq. 2
def test_end_loss_at_winter_solstice_noon_is_about_10_m(paper_fig2_site):
    site, height = paper_fig2_site["site"], paper_fig2_site["tube_height"]
    times = _day(site, "2025-12-21")
    position = geometry.solar_position(times, site.latitude, site.longitude)
    noon = position["apparent_elevation"].idxmax()
    altitude = position.loc[noon, "apparent_elevation"]
    shift = geometry.end_loss_length(
        position["apparent_elevation"], position["azimuth"], paper_fig2_site["mirror_distance"], height
    )
    assert isinstance(shift, pd.Series) and shift.index.equals(times)
    # first principles: at noon the sun is due South, so k = h / tan(altitude)
    assert shift[noon] == pytest.approx(height / np.tan(np.radians(altitude)), abs=5e-3)
    # noon altitude 90 - 40 - 23.44 = 26.56 deg gives h / tan = 10.0 m (the paper's Fig. 2)
    assert height / np.tan(np.radians(90.0 - 40.0 - OBLIQUITY_DEG)) == pytest.approx(10.0, abs=0.02)
    assert shift[noon] == pytest.approx(10.0, abs=0.3)


def test_end_loss_at_summer_solstice_stays_small_and_changes_sign(paper_fig2_site):
    site, height = paper_fig2_site["site"], paper_fig2_site["tube_height"]
    position = geometry.solar_position(_day(site, "2025-06-21"), site.latitude, site.longitude)
    position = position[position["apparent_elevation"] > 0.0]
    shift = geometry.end_loss_length(position["apparent_elevation"], position["azimuth"], 0.0, height)
    # The paper's "within about 2.2 m all day" holds while the sun is above ~8 deg
    operating = shift[position["apparent_elevation"] > 10.0]
    assert operating.abs().max() <= 2.2
    assert operating.min() < 0.0 < operating.max()
    # At the horizon the sun's North component is sin(decl) / cos(lat), so from first
    # principles |k| reaches h * y / sqrt(1 - y^2) = 3.04 m at sunrise (more with refraction).
    north = np.sin(np.radians(OBLIQUITY_DEG)) / np.cos(np.radians(site.latitude))
    assert shift.abs().max() == pytest.approx(height * north / np.sqrt(1.0 - north**2), abs=0.15)


def test_end_loss_sign_and_size_match_a_traced_ray(rng):
    """Trace the ray reflected by the single-axis mirror up to the tube, by hand."""
    sun = _random_sun(rng, 200)
    distance = rng.uniform(-6.0, 6.0, 200)
    height = 4.0
    elevation = np.degrees(np.arcsin(sun[:, 2]))
    azimuth = np.degrees(np.arctan2(sun[:, 0], sun[:, 1]))
    beta = geometry.single_axis_tilt(elevation, azimuth, distance, height)
    normal = np.column_stack([np.cos(beta), np.zeros_like(beta), np.sin(beta)])
    reflected = 2.0 * np.sum(sun * normal, axis=1, keepdims=True) * normal - sun
    # march from (d, 0, 0) until the ray reaches the tube height
    steps = height / reflected[:, 2]
    landing = np.array([distance, np.zeros_like(distance), np.zeros_like(distance)]).T + steps[:, None] * reflected
    np.testing.assert_allclose(landing[:, 0], 0.0, atol=1e-9)  # it hits the tube (x = 0)
    shift = geometry.end_loss_length(elevation, azimuth, distance, height)
    np.testing.assert_allclose(shift, landing[:, 1], rtol=1e-10, atol=1e-10)


# --------------------------------------------------------------------------- reflections
def test_single_axis_mirror_reflects_projected_sun_onto_the_tube(rng):
    n = 500
    sun = _random_sun(rng, n)
    distance = rng.uniform(-8.0, 8.0, n)
    height = rng.uniform(1.0, 10.0, n)
    elevation = np.degrees(np.arcsin(sun[:, 2]))
    azimuth = np.degrees(np.arctan2(sun[:, 0], sun[:, 1]))
    beta = np.array([geometry.single_axis_tilt(e, a, d, h) for e, a, d, h in zip(elevation, azimuth, distance, height)])
    projected = sun[:, [0, 2]] / np.linalg.norm(sun[:, [0, 2]], axis=1, keepdims=True)
    normal = np.column_stack([np.cos(beta), np.sin(beta)])
    reflected = 2.0 * np.sum(projected * normal, axis=1, keepdims=True) * normal - projected
    target = np.column_stack([-distance, height]) / np.hypot(distance, height)[:, None]
    pad = np.zeros((n, 1))
    angle = _angle_between(np.hstack([reflected, pad]), np.hstack([target, pad]))
    assert angle.max() < 1e-9


def test_two_axis_mirror_reflects_sun_onto_the_tube_point(rng):
    n = 1000
    sun = _random_sun(rng, n)
    distance = rng.uniform(-8.0, 8.0, n)
    height = 3.0
    normal = np.column_stack(geometry.two_axis_normal(sun[:, 0], sun[:, 1], sun[:, 2], distance, height))
    np.testing.assert_allclose(np.linalg.norm(normal, axis=1), 1.0, atol=1e-14)
    reflected = 2.0 * np.sum(sun * normal, axis=1, keepdims=True) * normal - sun
    target = np.column_stack([-distance, np.zeros(n), np.full(n, height)])
    assert _angle_between(reflected, target).max() < 1e-9


def test_primary_and_secondary_rebuild_the_normal(rng):
    sun = _random_sun(rng, 1000)
    distance = rng.uniform(-8.0, 8.0, 1000)
    normal = np.column_stack(geometry.two_axis_normal(sun[:, 0], sun[:, 1], sun[:, 2], distance, 5.0))
    primary, secondary = geometry.two_axis_angles_from_normal(normal[:, 0], normal[:, 1], normal[:, 2])
    rebuilt = np.array([_rotation_y(p) @ _rotation_x(q) @ [0.0, 0.0, 1.0] for p, q in zip(primary, secondary)])
    np.testing.assert_allclose(rebuilt, normal, rtol=0, atol=1e-12)


def test_two_axis_sign_conventions():
    # morning sun in the East, central mirror: the normal tilts East -> primary > 0
    primary, secondary = geometry.two_axis_angles(np.array([30.0]), np.array([90.0]), 0.0, 3.0)
    assert primary[0] > 0.0 and secondary[0] == pytest.approx(0.0, abs=1e-15)
    # noon sun due South: the normal tilts South (-y) -> secondary > 0, primary 0,
    # and for d = 0 it bisects zenith and sun: secondary = (90 - altitude) / 2
    primary, secondary = geometry.two_axis_angles(np.array([30.0]), np.array([180.0]), 0.0, 3.0)
    assert primary[0] == pytest.approx(0.0, abs=1e-15)
    assert secondary[0] == pytest.approx(np.radians(30.0), abs=1e-12)


def test_primary_is_minus_the_papers_eq3_and_secondary_is_eq4(rng):
    normal = _random_sun(rng, 300)  # any upward unit normal
    normal_azimuth = np.arctan2(normal[:, 0], normal[:, 1])  # from +y toward +x
    normal_altitude = np.arcsin(normal[:, 2])
    paper_primary = np.arctan(-np.sin(normal_azimuth) / np.tan(normal_altitude))  # eq. 3
    paper_secondary = -np.arcsin(np.cos(normal_altitude) * np.cos(normal_azimuth))  # eq. 4
    primary, secondary = geometry.two_axis_angles_from_normal(normal[:, 0], normal[:, 1], normal[:, 2])
    np.testing.assert_allclose(primary, -paper_primary, atol=1e-9)
    np.testing.assert_allclose(secondary, paper_secondary, atol=1e-9)


# --------------------------------------------------------------------------- field
def test_field_distances_and_primary_errors_at_noon():
    distances = geometry.field_distances(13, spacing=0.5)
    np.testing.assert_allclose(distances, (np.arange(13) - 6) * 0.5)
    assert distances[6] == 0.0
    altitude = 35.0
    errors = geometry.field_primary_errors(pd.Series([altitude]), pd.Series([180.0]), 3.0, distances)
    assert errors.shape == (1, 13)
    # sun due South: the central primary is 0; a mirror at d tilts toward the tube only,
    # n ~ S + T with S_x = 0, so its primary is atan2(-d / L, sin(alt) + h / L)
    slant = np.hypot(distances, 3.0)
    expected = np.arctan2(-distances / slant, np.sin(np.radians(altitude)) + 3.0 / slant)
    np.testing.assert_allclose(errors.iloc[0].to_numpy(), expected, atol=1e-12)
    assert errors.iloc[0, 6] == 0.0


@pytest.mark.parametrize("n_mirrors", [0, 12, 2.5, True])
def test_field_distances_rejects_bad_counts(n_mirrors):
    with pytest.raises(InputError, match="n_mirrors"):
        geometry.field_distances(n_mirrors)


# --------------------------------------------------------------------------- transmission, eqs. 12-15
def test_transmission_hand_check_and_round_trip(paper_transmission):
    r, s = paper_transmission["pinion_radius"], paper_transmission["lever_arm"]
    delta = np.radians(2.0)
    # panel 0 -> delta: rack travel s tan(delta) = r * rotor angle
    rotor = geometry.rotor_angle_from_panel(delta, 0.0, r, s)
    assert rotor == pytest.approx(0.3 / 2.5e-3 * np.tan(delta), rel=1e-14)
    assert np.degrees(rotor) == pytest.approx(240.1, abs=0.1)  # 120 * tan(2 deg) rad
    panel = pd.Series(np.radians(np.linspace(-60.0, 60.0, 25)))
    rotor = geometry.rotor_angle_from_panel(panel, np.radians(10.0), r, s, rotor_angle0=0.7)
    assert isinstance(rotor, pd.Series)
    back = geometry.panel_angle_from_rotor(rotor, np.radians(10.0), r, s, rotor_angle0=0.7)
    assert isinstance(back, pd.Series)
    np.testing.assert_allclose(back, panel, atol=1e-13)
    assert geometry.rotor_angle_from_panel(np.radians(10.0), np.radians(10.0), r, s, 0.7) == pytest.approx(0.7)


def test_speed_relation_matches_finite_difference_of_the_map(paper_transmission):
    r, s = paper_transmission["pinion_radius"], paper_transmission["lever_arm"]
    panel = np.radians(np.array([-50.0, -10.0, 0.0, 25.0, 70.0]))
    panel_speed = np.full(5, 1e-3)  # [rad/s]
    rotor_speed = geometry.rotor_speed_from_panel_speed(panel, panel_speed, r, s)
    dt_ = 1e-3
    rotor_plus = geometry.rotor_angle_from_panel(panel + panel_speed * dt_, 0.0, r, s)
    rotor_minus = geometry.rotor_angle_from_panel(panel - panel_speed * dt_, 0.0, r, s)
    np.testing.assert_allclose(rotor_speed, (rotor_plus - rotor_minus) / (2 * dt_), rtol=1e-7)
    back = r * rotor_speed * np.cos(panel) ** 2 / s  # the inverse of eq. 15
    np.testing.assert_allclose(back, panel_speed, rtol=1e-13)


# --------------------------------------------------------------------------- reference and stow
@pytest.fixture
def sunset_window(paper_fig2_site):
    """21 January 2025, 16:30-18:00 Europe/Rome: sunset at 40 N, 14.25 E is near 17:05."""
    site = paper_fig2_site["site"]
    return site, geometry.time_window("2025-01-21 16:30", "2025-01-21 18:00", "1min", site.timezone)


def test_reference_matches_two_axis_secondary_while_the_sun_is_up(sunset_window):
    site, times = sunset_window
    plant = geometry.Plant(tube_height=3.0)
    reference = geometry.panel_angle_reference(times, site, plant, 1.5, axis="secondary")
    position = geometry.solar_position(times, site.latitude, site.longitude)
    up = position["apparent_elevation"] > 0
    # first principles: n = (S + T) / |S + T|, secondary = -arcsin(n_y)
    alt, az = np.radians(position["apparent_elevation"]), np.radians(position["azimuth"])
    sun = np.column_stack([np.cos(alt) * np.sin(az), np.cos(alt) * np.cos(az), np.sin(alt)])
    target = np.array([-1.5, 0.0, 3.0]) / np.hypot(1.5, 3.0)
    normal = (sun + target) / np.linalg.norm(sun + target, axis=1, keepdims=True)
    np.testing.assert_allclose(reference[up], -np.arcsin(normal[up, 1]), atol=1e-12)
    primary = geometry.panel_angle_reference(times, site, plant, 1.5, axis="primary")
    np.testing.assert_allclose(primary[up], np.arctan2(normal[up, 0], normal[up, 2]), atol=1e-12)


def test_stow_hold_keeps_the_last_valid_angle_across_sunset(sunset_window):
    site, times = sunset_window
    plant = geometry.Plant(tube_height=3.0)
    reference = geometry.panel_angle_reference(times, site, plant, 0.0, stow="hold")
    elevation = geometry.solar_position(times, site.latitude, site.longitude)["apparent_elevation"]
    up = elevation > 0
    assert up.any() and (~up).any()
    assert not reference.isna().any()
    assert reference.name == "panel_angle_ref" and reference.index.equals(times)
    last_valid = reference[up].iloc[-1]
    assert (reference[~up] == last_valid).all()
    assert reference[up].nunique() > 1  # it did track before sunset


def test_stow_goes_to_the_stow_angle_and_hold_fills_before_sunrise(paper_fig2_site):
    site = paper_fig2_site["site"]
    plant = geometry.Plant(tube_height=3.0)
    times = geometry.time_window("2025-01-21 06:30", "2025-01-21 08:30", "1min", site.timezone)
    up = geometry.solar_position(times, site.latitude, site.longitude)["apparent_elevation"] > 0
    assert up.any() and (~up).any()
    stowed = geometry.panel_angle_reference(times, site, plant, 0.0, stow="stow", stow_angle=-0.2)
    assert not stowed.isna().any()
    assert (stowed[~up] == -0.2).all()
    held = geometry.panel_angle_reference(times, site, plant, 0.0, stow="hold")
    assert (held[~up] == held[up].iloc[0]).all()  # before the first valid: the first valid
    np.testing.assert_array_equal(held[up], stowed[up])


def test_hold_keeps_the_evening_angle_through_the_night_not_the_next_morning(paper_fig2_site):
    site = paper_fig2_site["site"]
    times = geometry.time_window("2025-01-21 15:00", "2025-01-22 10:00", "10min", site.timezone)
    up = geometry.solar_position(times, site.latitude, site.longitude)["apparent_elevation"].to_numpy() > 0
    reference = geometry.panel_angle_reference(
        times, site, geometry.Plant(tube_height=3.0), 0.0, axis="primary", stow="hold"
    )
    night = np.flatnonzero(~up)
    evening = reference.iloc[night[0] - 1]
    morning = reference.iloc[night[-1] + 1]
    assert evening < 0.0 < morning  # the primary faces West at sunset, East at sunrise
    assert (reference.iloc[night] == evening).all()


def test_a_window_with_no_sun_holds_the_stow_angle(paper_fig2_site):
    site = paper_fig2_site["site"]
    times = geometry.time_window("2025-01-21 00:00", "2025-01-21 01:00", "10min", site.timezone)
    reference = geometry.panel_angle_reference(
        times, site, geometry.Plant(tube_height=3.0), 0.0, stow="hold", stow_angle=0.1
    )
    assert (reference == 0.1).all()


# --------------------------------------------------------------------------- bad input
@pytest.fixture
def good_times():
    return pd.date_range("2025-01-21 12:00", periods=3, freq="1min", tz="Europe/Rome")


@pytest.mark.parametrize(
    ("call", "parameter"),
    [
        (lambda t: geometry.Site(latitude=91.0, longitude=0.0), "latitude"),
        (lambda t: geometry.Site(latitude=-90.5, longitude=0.0), "latitude"),
        (lambda t: geometry.Site(latitude=40.0, longitude=180.5), "longitude"),
        (lambda t: geometry.solar_position(t, 95.0, 0.0), "latitude"),
        (lambda t: geometry.solar_position(t, 40.0, -200.0), "longitude"),
        (lambda t: geometry.solar_position(t.tz_localize(None), 40.0, 0.0), "timezone-aware"),
        (lambda t: geometry.solar_position(t[:0], 40.0, 0.0), "empty"),
        (lambda t: geometry.Site(latitude=40.0, longitude=0.0, timezone="Europe/Atlantis"), "timezone"),
        (lambda t: geometry.time_window("2025-01-21 12:00", "2025-01-21 11:00", "1s", "Nowhere/City"), "timezone"),
        (lambda t: geometry.time_window("2025-01-21 12:00", "2025-01-21 12:00", "1s", "UTC"), "empty window"),
        (lambda t: geometry.time_window("2025-01-21 12:05", "2025-01-21 12:00", "1s", "UTC"), "empty window"),
        (lambda t: geometry.time_window("2025-01-21 12:00", "2025-01-21 12:05"), "start"),
        (lambda t: geometry.Plant(tube_height=0.0), "tube_height"),
        (lambda t: geometry.Plant(tube_height=-3.0), "tube_height"),
        (lambda t: geometry.end_loss_length(30.0, 180.0, 0.0, 0.0), "tube_height"),
        (lambda t: geometry.two_axis_angles(30.0, 180.0, 0.0, -1.0), "tube_height"),
        (lambda t: geometry.Plant(tube_height=3.0, orientation="NE"), "orientation"),
        (lambda t: geometry.rotor_angle_from_panel(0.1, 0.0, 0.0, 0.3), "pinion_radius"),
        (lambda t: geometry.rotor_angle_from_panel(0.1, 0.0, 2.5e-3, -0.3), "lever_arm"),
        (lambda t: geometry.panel_angle_from_rotor(0.1, 0.0, -1.0, 0.3), "pinion_radius"),
        (lambda t: geometry.rotor_speed_from_panel_speed(0.1, 0.0, 2.5e-3, 0.0), "lever_arm"),
        (lambda t: geometry.rotor_angle_from_panel(np.pi / 2, 0.0, 2.5e-3, 0.3), "panel_angle"),
        (lambda t: geometry.field_distances(13, spacing=0.0), "spacing"),
    ],
)
def test_bad_input_raises_input_error_naming_the_parameter(call, parameter, good_times):
    with pytest.raises(InputError, match=parameter):
        call(good_times)


@pytest.mark.parametrize(
    ("kwargs", "parameter"),
    [({"axis": "tertiary"}, "axis"), ({"stow": "park"}, "stow"), ({"stow_angle": 2.0}, "stow_angle")],
)
def test_reference_rejects_unknown_axis_and_stow_policy(kwargs, parameter, good_times, paper_fig2_site):
    with pytest.raises(InputError, match=parameter):
        geometry.panel_angle_reference(
            good_times, paper_fig2_site["site"], geometry.Plant(tube_height=3.0), 0.0, **kwargs
        )


def test_reference_rejects_naive_and_empty_times(good_times, paper_fig2_site):
    site, plant = paper_fig2_site["site"], geometry.Plant(tube_height=3.0)
    with pytest.raises(InputError, match="timezone-aware"):
        geometry.panel_angle_reference(good_times.tz_localize(None), site, plant, 0.0)
    with pytest.raises(InputError, match="empty"):
        geometry.panel_angle_reference(good_times[:0], site, plant, 0.0)


def test_input_error_is_a_value_error():
    with pytest.raises(ValueError):
        geometry.Site(latitude=100.0, longitude=0.0)


def test_geometry_does_not_import_matplotlib():
    code = "import sys, heliostep.solar; sys.exit('matplotlib' in sys.modules)"
    assert subprocess.run([sys.executable, "-c", code], check=False).returncode == 0
