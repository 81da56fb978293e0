"""The receiver's own shadow on the mirrors (:mod:`heliostep.solar.receiver_shadow`) from first principles and
against the Monte Carlo ray tracer written for the tests (``tests/support/mirror_tracer.py``: the receiver a cylinder
about (0, y, h), each sun ray tested by the closest approach of two lines in 3-D; 40 000 points per mirror,
standard error <= 0.0025), alone and united with the neighbours' shading and blocking
(:func:`heliostep.solar.shading.row_losses` with ``receiver``)."""

from __future__ import annotations

import numpy as np
import pytest

from heliostep.solar.receiver_shadow import receiver_shadow_fraction, receiver_width, trapezoid_cdf
from heliostep.solar.shading import row_losses
from mirror_tracer import N_ROWS, layout, sun_vectors, trace, tracking_normals

#: Around solar noon (12:14 CET at 14.25 E on 21 January), when the receiver's shadow lies on the
#: central mirrors, and off noon.
INSTANTS = ["2025-12-21 12:00", "2025-12-21 11:00", "2025-06-21 13:20", "2025-03-21 12:30", "2025-01-21 12:10"]


def test_a_horizontal_mirror_under_the_tube_at_noon_loses_d_over_w():
    # the sun due south of a North-South tube (S_x = 0) over a horizontal mirror centred under it: the tube's
    # shadow is a band of the tube's width D straight down the mirror, D / w of it, whatever the elevation
    for elevation in (20.0, 45.0, 70.0):
        e = np.radians(elevation)
        sun = np.array([0.0, -np.cos(e), np.sin(e)])
        for diameter, width in ((0.07, 0.6), (0.07, 0.3), (0.3, 0.3), (0.5, 0.3)):
            fraction = receiver_shadow_fraction(sun, [0.0, 0.0, 1.0], 0.0, 3.0, diameter, width, 1.5)
            assert fraction == pytest.approx(min(diameter / width, 1.0), abs=1e-12)
    # a horizontal mirror 1 m East, the sun theta = atan(1 / h) West of the zenith in the cross-section: the
    # tube's shadow is centred on it, and a cylinder's shadow on a plane at theta from its normal is D / cos theta
    sun = lambda theta: np.array([-np.sin(theta), 0.0, np.cos(theta)])  # noqa: E731, theta toward the West
    h = 3.0
    theta = np.arctan(1.0 / h)
    on = receiver_shadow_fraction(sun(theta), [0.0, 0.0, 1.0], 1.0, h, 0.07, 0.3, 1.5)
    assert on == pytest.approx(0.07 / np.cos(theta) / 0.3, abs=1e-12)
    assert receiver_shadow_fraction(sun(-np.arctan(1.0 / h)), [0.0, 0.0, 1.0], 1.0, h, 0.07, 0.3, 1.5) == 0.0


def test_the_trapezoid_cdf_from_first_principles():
    rng = np.random.default_rng(5)
    x = rng.uniform(-0.4, 0.4, 400_000) + rng.uniform(-0.1, 0.1, 400_000)  # U(-0.4, 0.4) + U(-0.1, 0.1)
    for z in (-0.55, -0.45, -0.3, -0.05, 0.0, 0.2, 0.33, 0.48, 0.6):
        assert trapezoid_cdf(z, 0.4, 0.1) == pytest.approx(np.mean(x <= z), abs=0.003)
    assert trapezoid_cdf(0.1, 0.4, 0.0) == pytest.approx(0.625)  # a box
    assert trapezoid_cdf([-1e-9, 1e-9], 0.0, 0.0).tolist() == [0.0, 1.0]  # a point: a step at 0
    assert receiver_width(0.07, None) == 0.07 and receiver_width(0.07, {"aperture_width": 0.3}) == 0.3


@pytest.mark.parametrize(
    "spacing, width, h, two_axis, diameter",
    [(0.6, 0.3, 3.0, True, 0.07), (0.6, 0.3, 3.0, True, 0.3), (0.6, 0.6, 5.0, False, 0.07)],
)
def test_receiver_shadow_alone_and_with_the_neighbours_match_the_ray_tracer(spacing, width, h, two_axis, diameter):
    rng = np.random.default_rng(23)
    length = 1.5
    sun = sun_vectors(INSTANTS)
    distances, grid, ys = layout(spacing, along=length if two_axis else None, n_along=7)
    normals = tracking_normals(sun, distances, h, two_axis=two_axis)
    along = length if two_axis else None
    closed = row_losses(sun, normals, distances, width, along, along, receiver=(h, diameter))
    alone = receiver_shadow_fraction(sun[:, None, :], normals, distances[None, :], h, diameter, width, length)
    seen = 0.0
    for t in range(len(INSTANTS)):
        for i in (5, 6, 7):  # the central mirrors, where the shadow falls near noon, and their neighbours
            target = (len(ys) // 2) * N_ROWS + i if two_axis else i
            mirrors = np.tile(normals[t], (len(ys), 1)) if two_axis else normals[t]
            run = length if two_axis else 200.0  # single-axis rows: long, the tracer samples 2 m of them
            solo = trace(sun[t], mirrors[target : target + 1], grid[target : target + 1], 0, width, run, h, rng,
                         receiver_radius=diameter / 2)  # fmt: skip
            full = trace(sun[t], mirrors, grid, target, width, run, h, rng, receiver_radius=diameter / 2)
            where = (INSTANTS[t], i)
            assert alone[t, i] == pytest.approx(solo[0], abs=0.01), where  # exact: the tracer's sampling
            assert closed["receiver_shadow"][t, i] == pytest.approx(solo[0], abs=0.01), where
            assert closed["shading"][t, i] == pytest.approx(full[0], abs=0.02), where
            assert closed["lost"][t, i] == pytest.approx(full[2], abs=0.02), where
            seen = max(seen, solo[0])
    assert seen > 0.1  # the instants put the shadow on the mirrors
