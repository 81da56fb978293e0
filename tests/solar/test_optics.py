"""Tests of heliostep.solar.optics against first principles and the seeds' check values."""

from __future__ import annotations

import numpy as np
import pytest

from heliostep.errors import InputError
from heliostep.solar import optics, tracking
from heliostep.solar.sun import sun_vector

# seed 004 (energy-chain Fresnel concentrator), Section 3: rho = 0.80, tau = 0.85, alpha = 0.95
RHO, TAU, ALPHA = 0.80, 0.85, 0.95
# [paper] Section 2 / PHYSICS.md: d = 0, h = 5 m, 40 deg N, noon 21 December -> k ~ 10 m
PAPER_TUBE_HEIGHT = 5.0  # [m]
PAPER_NOON_DEC21_ELEVATION = 90.0 - 40.0 - 23.44  # [deg], 90 - latitude - obliquity
PAPER_K_DEC21 = 10.0  # [m], "k ~ 10 m"


def _sun_grid():
    elevation = np.array([10.0, 26.6, 45.0, 70.0, 85.0, 30.0])
    azimuth = np.array([100.0, 180.0, 135.0, 200.0, 260.0, 300.0])
    return sun_vector(elevation, azimuth)


@pytest.mark.parametrize("distance", [-5.0, 0.0, 2.4, 6.0])
def test_ideal_mirror_sends_central_ray_to_the_tube_axis(distance):
    sun = _sun_grid()
    normal = tracking.two_axis_normal(*sun, mirror_distance=distance, tube_height=3.0)
    ray = optics.reflect(*sun, *normal)
    transverse, longitudinal, slant = optics.receiver_miss(*ray, distance, 3.0)
    np.testing.assert_allclose(transverse, 0.0, atol=1e-12)
    np.testing.assert_allclose(longitudinal, 0.0, atol=1e-12)
    np.testing.assert_allclose(slant, np.hypot(distance, 3.0), rtol=1e-12)
    # the same through the rotation angles (the trace's panel attitude)
    primary, secondary = tracking.two_axis_angles_from_normal(*normal)
    np.testing.assert_allclose(np.stack(optics.mirror_normal(primary, secondary)), np.stack(normal), atol=1e-12)


def test_reflected_ray_is_unit_and_obeys_equal_angles():
    sun = _sun_grid()
    normal = optics.mirror_normal(
        np.array([0.1, -0.3, 0.2, 0.0, 0.5, -0.1]), np.array([0.05, 0.0, -0.2, 0.3, 0.1, 0.0])
    )
    ray = optics.reflect(*sun, *normal)
    np.testing.assert_allclose(np.linalg.norm(np.stack(ray), axis=0), 1.0, rtol=1e-12)
    cos_in = sum(s * n for s, n in zip(sun, normal))
    cos_out = sum(r * n for r, n in zip(ray, normal))
    np.testing.assert_allclose(cos_in, cos_out, rtol=1e-12)


@pytest.mark.parametrize("delta", [1e-4, 1e-3, 0.02, 0.1])
def test_known_tilt_gives_closed_form_miss(delta):
    h = 4.0
    zenith = (np.array([0.0]), np.array([0.0]), np.array([1.0]))
    # secondary tilt delta, sun at zenith, d = 0: the ray turns by 2 delta along the tube
    ray = optics.reflect(*zenith, *optics.mirror_normal(0.0, delta))
    transverse, longitudinal, slant = optics.receiver_miss(*ray, 0.0, h)
    np.testing.assert_allclose(transverse, 0.0, atol=1e-14)
    np.testing.assert_allclose(longitudinal, -h * np.tan(2 * delta), rtol=1e-12)
    np.testing.assert_allclose(slant, h / np.cos(2 * delta), rtol=1e-12)
    # primary tilt delta: the ray turns by 2 delta in the cross-section; the axis is at h sin(2 delta)
    ray = optics.reflect(*zenith, *optics.mirror_normal(delta, 0.0))
    transverse, longitudinal, _ = optics.receiver_miss(*ray, 0.0, h)
    np.testing.assert_allclose(transverse, h * np.sin(2 * delta), rtol=1e-12)
    np.testing.assert_allclose(longitudinal, 0.0, atol=1e-14)


def test_cosine_factor():
    np.testing.assert_allclose(optics.cosine_factor(0.0, 0.0, 1.0, *optics.mirror_normal(0.3, 0.0)), np.cos(0.3))
    assert optics.cosine_factor(0.0, 0.0, -1.0, 0.0, 0.0, 1.0) == 0.0


def test_seed_check_values():
    assert optics.optical_chain(RHO, TAU, ALPHA) == pytest.approx(0.646)
    with pytest.raises(InputError, match="reflectivity"):
        optics.optical_chain(1.2, TAU, ALPHA)


def test_end_effect():
    # a single-axis mirror at noon on 21 December, 40 deg N: its light shifts by k ~ 10 m
    sun = sun_vector(np.array([PAPER_NOON_DEC21_ELEVATION]), np.array([180.0]))
    beta = tracking.single_axis_tilt(PAPER_NOON_DEC21_ELEVATION, 180.0, 0.0, PAPER_TUBE_HEIGHT)
    normal = (np.cos(beta), np.zeros(1), np.sin(beta))
    ray = optics.reflect(*sun, *normal)
    transverse, k, _ = optics.receiver_miss(*ray, 0.0, PAPER_TUBE_HEIGHT)
    np.testing.assert_allclose(transverse, 0.0, atol=1e-12)
    assert abs(k[0]) == pytest.approx(PAPER_K_DEC21, rel=0.02)
    k_eq2 = tracking.end_loss_length(PAPER_NOON_DEC21_ELEVATION, 180.0, 0.0, PAPER_TUBE_HEIGHT)
    np.testing.assert_allclose(k, k_eq2, rtol=1e-12)
    # an end mirror (1.5 m long, centred 0.75 m inside the tube's end at y = 0): light past the end is lost
    assert optics.end_fraction(0.0, 1.5, 0.75, 0.0, 100.0) == 1.0
    assert optics.end_fraction(-0.75, 1.5, 0.75, 0.0, 100.0) == pytest.approx(0.5)
    assert optics.end_fraction(-10.0, 1.5, 0.75, 0.0, 100.0) == 0.0
