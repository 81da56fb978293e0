"""heliostep.drive.wind and wind_load: the wind's direction. The load comes from the wind's component
normal to the panel's axis (the cross-flow principle); the moment is checked against the formula
written here for several directions and axes, against a 3-D vector calculation of the flat plate's
normal force at its centre of pressure, and through a weather file written here with a direction
column (EPW and TMY3)."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

from heliostep.drive import wind
from heliostep.drive.inputs import prepare_inputs
from heliostep.drive.wind_load import moment_signal, panel_axis_azimuth, wind_speed_knots
from heliostep.errors import InputError
from heliostep.paths import scenarios_dir
from heliostep.scenario import load_scenario
from weather_files import write_epw, write_tmy3

AREA, CHORD, DENSITY, GUST = 0.45, 0.3, 1.2, 1.52


def _flat_plate(alpha: float) -> tuple[float, float]:
    """Hoerner's C_N and Joessel's x_cp / c at the angle of attack ``alpha`` [rad] in [0, pi/2]."""
    if alpha == 0.0:
        return 0.0, 0.195
    return 1.0 / (0.222 + 0.283 / math.sin(alpha)), 0.195 + 0.305 * math.sin(alpha)


def _formula(speed, direction_deg, axis_deg, panel_deg):
    """M = sign(theta) C_M(|theta|) 1/2 rho (G v sin(phi - psi))^2 A c: the normal component's moment."""
    normal_speed = speed * math.sin(math.radians(direction_deg - axis_deg))
    c_n, x_cp = _flat_plate(math.radians(abs(panel_deg)))
    q = 0.5 * DENSITY * (GUST * normal_speed) ** 2
    return math.copysign(1.0, panel_deg) * c_n * (0.5 - x_cp) * q * AREA * CHORD if panel_deg else 0.0


def _vector_moment(speed, direction_deg, axis_deg, panel_deg):
    """The same from the geometry in 3-D (x east, y north, z up): the wind's velocity less its part along
    the axis, the plate's normal force C_N q A along its normal, at x_cp from the edge the flow meets
    first; the moment about the axis, (r x F) . a. Nothing of the module's sign logic is used."""
    psi, phi, theta = (math.radians(a) for a in (axis_deg, direction_deg, panel_deg))
    axis = np.array([math.sin(psi), math.cos(psi), 0.0])
    side = np.array([math.cos(psi), -math.sin(psi), 0.0])  # azimuth psi + 90 deg
    up = np.array([0.0, 0.0, 1.0])
    normal = math.cos(theta) * up + math.sin(theta) * side  # the normal turned by theta about the axis
    across = math.cos(theta) * side - math.sin(theta) * up  # the chord's direction
    velocity = -speed * np.array([math.sin(phi), math.cos(phi), 0.0])  # blowing FROM phi
    flow = velocity - (velocity @ axis) * axis  # the component normal to the axis
    magnitude = float(np.linalg.norm(flow))
    if magnitude < 1e-12:
        return 0.0
    alpha = math.asin(min(1.0, abs(flow @ normal) / magnitude))
    c_n, x_cp = _flat_plate(alpha)
    force = c_n * 0.5 * DENSITY * (GUST * magnitude) ** 2 * AREA * math.copysign(1.0, flow @ normal) * normal
    downstream = math.copysign(1.0, flow @ across) if abs(flow @ across) > 1e-12 else 1.0
    lever = downstream * across * CHORD * (x_cp - 0.5)  # from mid-chord; the leading edge at -downstream c/2
    return float(np.cross(lever, force) @ axis)


DIRECTIONS = [0.0, 30.0, 90.0, 135.0, 200.0, 270.0, 330.0]


@pytest.mark.parametrize("axis_deg", [0.0, 90.0, 20.0])
@pytest.mark.parametrize("direction_deg", DIRECTIONS)
@pytest.mark.parametrize("panel_deg", [-40.0, 25.0])
def test_moment_of_a_directed_wind_is_its_normal_components(axis_deg, direction_deg, panel_deg):
    got = wind.panel_wind_moment(
        14.0, math.radians(panel_deg), AREA, CHORD, DENSITY, GUST, direction=direction_deg, axis_azimuth=axis_deg
    )
    assert got == pytest.approx(_formula(14.0, direction_deg, axis_deg, panel_deg), rel=1e-12, abs=1e-12)
    assert got == pytest.approx(_vector_moment(14.0, direction_deg, axis_deg, panel_deg), rel=1e-9, abs=1e-12)


def test_the_worst_direction_is_normal_to_the_axis_and_along_it_there_is_no_load():
    panel = math.radians(25.0)
    worst = wind.panel_wind_moment(10.0, panel, AREA, CHORD, DENSITY)  # no direction: normal to the axis
    for direction in (90.0, 270.0):  # across a north-south axis, from east and from west
        assert wind.panel_wind_moment(10.0, panel, AREA, CHORD, DENSITY, direction=direction) == pytest.approx(worst)
    for direction in (0.0, 180.0, 360.0):  # along it
        assert wind.panel_wind_moment(10.0, panel, AREA, CHORD, DENSITY, direction=direction) == pytest.approx(
            0.0, abs=1e-12
        )
    angles = np.radians(np.arange(0.0, 360.0, 5.0))
    moments = wind.panel_wind_moment(10.0, panel, AREA, CHORD, DENSITY, direction=np.degrees(angles))
    assert np.all(np.abs(moments) <= abs(worst) * (1 + 1e-12))


def test_the_attack_angle_flips_with_the_side_and_the_flat_plates_moment_does_not():
    # from west (270 deg) the wind blows towards +x on a north-south axis, from east towards -x
    from_west, from_east = (wind.cross_wind_speed(10.0, d, 0.0) for d in (270.0, 90.0))
    assert float(from_west) == pytest.approx(10.0) and float(from_east) == pytest.approx(-10.0)
    theta = math.radians(30.0)
    assert float(wind.attack_angle(theta, from_west)) == pytest.approx(theta)
    assert float(wind.attack_angle(theta, from_east)) == pytest.approx(-theta)
    # a symmetric plate pivoted at mid-chord turns broadside either way: the same moment
    m_west = wind.cross_wind_moment(from_west, theta, AREA, CHORD, DENSITY)
    assert m_west > 0.0 and wind.cross_wind_moment(from_east, theta, AREA, CHORD, DENSITY) == pytest.approx(m_west)
    # an undefined direction (NaN: EPW's calm) is the worst case
    assert float(wind.cross_wind_speed(10.0, np.nan, 0.0)) == 10.0


def _scenario(path, *extra):
    return load_scenario(
        scenarios_dir() / "jan21-windy.yaml",
        ["wind.profile=null", f"wind.weather_file={path}", "wind.stow_speed=null", "wind.gust_factor=1.52", *extra],
    )


@pytest.mark.parametrize("write", [write_epw, write_tmy3], ids=["epw", "tmy3"])
def test_a_weather_files_direction_sets_the_normal_component(tmp_path, write):
    # 12 m/s from 60 deg at 11:00, 16 m/s from 120 deg at 12:00 (measured at the stamps)
    speeds, directions = {11: 12.0, 12: 16.0}, {11: 60.0, 12: 120.0}
    path = write(
        tmp_path / ("w.epw" if write is write_epw else "w.csv"),
        latitude=40.0,
        longitude=14.25,
        wind_of_hour=lambda h: speeds.get(h, 5.0),
        direction_of_hour=lambda h: directions.get(h, 90.0),
    )
    scenario = _scenario(path)
    assert panel_axis_azimuth(scenario) == 0.0  # the primary axis along the north-south tube
    start = pd.Timestamp("2025-01-21 11:15", tz="Europe/Rome")  # = 11:15 of the file's UTC+1
    knots = wind_speed_knots(scenario, start, 1800.0)
    # the direction through the wind's vector at 11:15 and 11:45 (a quarter and three quarters of the way)
    for t, share in ((0.0, 0.25), (1800.0, 0.75)):
        east = np.interp(share, [0, 1], [12.0 * math.sin(math.radians(60.0)), 16.0 * math.sin(math.radians(120.0))])
        north = np.interp(share, [0, 1], [12.0 * math.cos(math.radians(60.0)), 16.0 * math.cos(math.radians(120.0))])
        speed = 12.0 + 4.0 * share
        direction = math.degrees(math.atan2(east, north))
        expected = -speed * math.sin(math.radians(direction))  # u = -v sin(phi - 0)
        assert float(knots.cross_speed(t, 0.0)) == pytest.approx(expected, rel=1e-9)
    # the m_ext signal on a panel held at 20 deg: each hold takes its larger end, the formula here
    signal = moment_signal(scenario, knots, np.zeros(0), lambda t: np.full(np.shape(t), math.radians(20.0)), 1800.0)
    temperature = 10.0 if write is write_epw else 15.0  # the EPW's dry bulb; TMY3 here has none: the ISA's
    density = 101325.0 / (287.05287 * (273.15 + temperature))  # the site at sea level
    c_n, x_cp = _flat_plate(math.radians(20.0))
    ends = np.concatenate([[0.0], signal.times, [1800.0]])
    u = knots.cross_speed(ends, 0.0)
    q = 0.5 * density * (1.52 * np.maximum(np.abs(u[:-1]), np.abs(u[1:]))) ** 2
    np.testing.assert_allclose(signal.values, -c_n * (0.5 - x_cp) * q * AREA * CHORD, rtol=1e-9)
    # the scenario's direction overrides the file's: along the axis there is no moment
    along = _scenario(path, "wind.direction=180")
    assert wind_speed_knots(along, start, 1800.0).cross_speed(900.0, 0.0) == pytest.approx(0.0, abs=1e-9)


def test_a_design_winds_direction_key_defaults_to_the_worst_case():
    base = load_scenario(scenarios_dir() / "jan21-windy.yaml")
    assert base.wind.direction is None
    start, duration = base.window_bounds()[0], 150.0
    worst = wind_speed_knots(base, start, duration)
    np.testing.assert_allclose(worst.cross_speed(worst.times, 0.0), worst.speed)
    # the secondary axis runs across the tube: 90 deg for a north-south plant
    assert panel_axis_azimuth(load_scenario(scenarios_dir() / "jan21-windy.yaml", ["mirror.axis=secondary"])) == 90.0
    oblique = wind_speed_knots(load_scenario(scenarios_dir() / "jan21-windy.yaml", ["wind.direction=300"]), start, 150)
    np.testing.assert_allclose(oblique.cross_speed(oblique.times, 0.0), -oblique.speed * math.sin(math.radians(300)))


def test_a_direction_without_a_wind_speed_is_an_input_error():
    with pytest.raises(InputError, match="wind.direction"):
        load_scenario(scenarios_dir() / "jan21-windy.yaml", ["wind.profile=null", "wind.direction=90"])
    with pytest.raises(InputError, match="wind.direction"):
        load_scenario(scenarios_dir() / "jan21-windy.yaml", ["wind.direction=400"])


def test_the_runs_wind_input_takes_the_files_direction(tmp_path):
    # the drive's m_ext signal as a run gets it (prepare_inputs): a wind from the north blows along the
    # primary axis of a north-south plant and loads nothing; from the east it is the worst case
    def signal(direction: float):
        path = write_epw(
            tmp_path / f"d{direction:g}.epw",
            latitude=40.0,
            longitude=14.25,
            wind_of_hour=lambda h: 10.0,
            direction_of_hour=lambda h: direction,
        )
        inputs = prepare_inputs(_scenario(path, 'window.start="11:15"', "window.duration=20"))
        return inputs.wind_signal

    along, across = signal(360.0), signal(90.0)  # EPW: 360 is north (0 is "undefined")
    assert np.max(np.abs(along.values)) < 1e-9 * np.max(np.abs(across.values))
    panel = across.angles  # the commanded panel angle over each hold
    c_n = 1.0 / (0.222 + 0.283 / np.sin(np.abs(panel)))
    cm = np.sign(panel) * c_n * (0.5 - 0.195 - 0.305 * np.sin(np.abs(panel)))
    density = 101325.0 / (287.05287 * 283.15)  # the EPW's dry bulb, 10 degC, at sea level
    np.testing.assert_allclose(across.values, -cm * 0.5 * density * (1.52 * 10.0) ** 2 * AREA * CHORD, rtol=1e-9)
