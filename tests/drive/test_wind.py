"""heliostep.drive.wind and heliostep.drive.stow: the wind's moment against the formula written here,
the sources' published values, the stow spans of a piecewise-linear speed."""

from __future__ import annotations

import math

import numpy as np
import pytest

from heliostep.drive import wind
from heliostep.drive.stow import plan_stow, stowed_spans, threshold_crossings


def _moment_here(speed, angle_deg, area, chord, density, gust):
    """M = sign(theta) C_M(|theta|) 1/2 rho (G v)^2 A c, C_M = C_N (1/2 - x_cp / c), written out."""
    alpha = math.radians(abs(angle_deg))
    if alpha == 0.0:
        return 0.0
    normal = 1.0 / (0.222 + 0.283 / math.sin(alpha))  # Hoerner, Fluid-Dynamic Drag (1965), flat plate
    centre = 0.195 + 0.305 * math.sin(alpha)  # Joessel's centre of pressure
    return math.copysign(1.0, angle_deg) * normal * (0.5 - centre) * 0.5 * density * (gust * speed) ** 2 * area * chord


@pytest.mark.parametrize("speed", [0.0, 5.0, 12.0, 15.0, 20.0, 25.0, 40.0])
@pytest.mark.parametrize("angle_deg", [-60.0, -25.0, -3.0, 0.0, 3.0, 25.0, 45.0, 89.0])
def test_moment_is_the_formula(speed, angle_deg):
    area, chord, density, gust = 0.45, 0.3, 1.1, 1.52
    expected = _moment_here(speed, angle_deg, area, chord, density, gust)
    got = wind.panel_wind_moment(speed, math.radians(angle_deg), area, chord, density, gust)
    assert got == pytest.approx(expected, rel=1e-12, abs=1e-15)
    assert wind.external_moment(speed, math.radians(angle_deg), area, chord, density, gust) == pytest.approx(-expected)


def test_moment_vectorised_equals_the_scalars():
    speeds, angles = np.array([3.0, 10.0, 25.0]), np.radians([-10.0, 20.0, 70.0])
    got = wind.panel_wind_moment(speeds, angles, 1.0, 0.5)
    expected = [
        _moment_here(v, math.degrees(a), 1.0, 0.5, wind.ISA_SEA_LEVEL_DENSITY, 1.0) for v, a in zip(speeds, angles)
    ]
    assert got == pytest.approx(expected, rel=1e-12)


def test_coefficients_take_their_sources_values():
    # Hoerner: a 2-D flat plate broadside has C_N = 1/(0.222 + 0.283) = 1.980 (its drag coefficient)
    assert float(wind.normal_force_coefficient(math.pi / 2)) == pytest.approx(1.980, abs=5e-4)
    # Joessel: the centre of pressure is at the middle broadside, at 0.195 c edge-on
    assert float(wind.centre_of_pressure(math.pi / 2)) == pytest.approx(0.5)
    assert float(wind.centre_of_pressure(0.0)) == pytest.approx(0.195)
    # no moment about the mid-chord flat (the stow attitude) or broadside; largest in between
    angles = np.radians(np.linspace(0.0, 90.0, 1801))
    cm = wind.moment_coefficient(angles)
    assert cm[0] == 0.0 and cm[-1] == pytest.approx(0.0, abs=1e-15)
    assert math.degrees(angles[np.argmax(cm)]) == pytest.approx(25.5, abs=0.5)
    assert cm.max() == pytest.approx(0.1975, abs=5e-4)


def test_moment_turns_the_panel_away_from_edge_on_whichever_side():
    # a flat plate pivoted at its middle turns broadside: M has the sign of theta_p, m_ext the opposite
    for angle in (np.radians(20.0), np.radians(-20.0)):
        assert np.sign(wind.panel_wind_moment(15.0, angle, 1.0, 1.0)) == np.sign(angle)


@pytest.mark.parametrize(
    "altitude, density",
    [(0.0, 1.2250), (1000.0, 1.1117), (2000.0, 1.0066), (3000.0, 0.9093)],  # ISO 2533 (ISA) table values
)
def test_air_density_is_the_standard_atmosphere(altitude, density):
    assert float(wind.air_density(altitude)) == pytest.approx(density, abs=2e-4)


def test_air_density_at_a_given_temperature_is_the_ideal_gas():
    # 101325 Pa at 30 degC: p / (R T) with R = 287.05 J/(kg K)
    assert float(wind.air_density(0.0, 30.0)) == pytest.approx(101325.0 / (287.05 * 303.15), rel=1e-4)


GUST = ([0.0, 20.0, 30.0, 60.0, 70.0, 150.0], [5.0, 5.0, 18.0, 18.0, 5.0, 5.0])


def test_threshold_crossings_of_a_linear_ramp_are_exact():
    up, down = threshold_crossings(*GUST, 12.0)
    assert up == pytest.approx([20.0 + 10.0 * 7.0 / 13.0])
    assert down == pytest.approx([60.0 + 10.0 * 6.0 / 13.0])


def test_return_comes_after_the_calm_time():
    (span,) = stowed_spans(*GUST, threshold=12.0, calm_time=60.0, end=150.0)
    assert span == pytest.approx((20.0 + 70.0 / 13.0, 60.0 + 60.0 / 13.0 + 60.0))


def test_a_gust_during_the_calm_time_restarts_it():
    times = [0.0, 10.0, 11.0, 20.0, 21.0, 30.0, 31.0, 200.0]
    speed = [5.0, 5.0, 20.0, 20.0, 5.0, 5.0, 20.0, 20.0]  # below from 20.5 s, above again from 30.5 s
    assert stowed_spans(times, speed, 12.0, calm_time=30.0, end=200.0) == [(pytest.approx(10.0 + 7.0 / 15.0), 200.0)]
    times = [0.0, 10.0, 11.0, 20.0, 21.0, 30.0, 31.0, 40.0, 41.0, 300.0]
    speed = [5.0, 5.0, 20.0, 20.0, 5.0, 5.0, 20.0, 20.0, 5.0, 5.0]
    ((start, back),) = stowed_spans(times, speed, 12.0, calm_time=30.0, end=300.0)
    assert back == pytest.approx(40.0 + 8.0 / 15.0 + 30.0)  # the calm counted from the last fall


def test_a_threshold_never_crossed_gives_no_stow():
    assert stowed_spans(*GUST, threshold=18.5, calm_time=60.0, end=150.0) == []


def test_stow_plan_slews_at_the_rate_holds_and_meets_the_moving_reference():
    times = np.linspace(0.0, 200.0, 401)

    def tracking(t):
        return np.radians(10.0) + np.radians(0.01) * np.asarray(t)  # 0.01 deg/s

    rate = np.radians(0.5)
    plan = plan_stow(times, tracking, [(20.0, 100.0)], 0.0, rate, 200.0)
    stow, back = plan.moves
    assert stow.end - stow.start == pytest.approx(math.radians(10.2) / rate)  # 10.2 deg at 0.5 deg/s
    assert back.start == 100.0
    # the return meets the reference where 0.5 deg/s (t - 100) = 10 + 0.01 t: t = 60 / 0.49 + ...
    t_meet = (10.0 + 0.5 * 100.0) / (0.5 - 0.01)
    assert back.end == pytest.approx(t_meet, rel=1e-9)
    held = (plan.times > stow.end) & (plan.times < back.start)
    assert np.all(plan.panel_angle[held] == 0.0)
    after = plan.times > back.end
    assert plan.panel_angle[after] == pytest.approx(tracking(plan.times[after]))
    assert plan.stowed == ((20.0, pytest.approx(t_meet)),)
