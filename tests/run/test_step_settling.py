"""A step's settling time from the swings of its ring (heliostep.run.step_settling) against a damped
oscillation written here, whose settling time is the last root of |x(t)| = 1 band, found by brentq."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.interpolate import CubicSpline
from scipy.optimize import brentq

from heliostep.run.step_settling import LOBES, lobes, settling_times, swings_at

#: A ring of 160 Hz (a stepper's rotor on its detent) starting 20 bands off (a step of 1/0.05 bands).
OMEGA, HEIGHT = 2 * np.pi * 160.0, 20.0
TIME = np.linspace(0.0, 0.3, 60001)


def _ring(decay: float, time: np.ndarray = TIME) -> np.ndarray:
    return -HEIGHT * np.exp(-decay * time) * np.cos(OMEGA * time)


def _settling(decay: float, shift: float = 0.0) -> float:
    """The last time the ring less ``shift`` leaves the band, between the samples where it last does."""
    outside = np.flatnonzero(np.abs(_ring(decay) - shift) > 1.0)
    j = outside[-1]
    return brentq(lambda t: abs(_ring(decay, np.array([t]))[0] - shift) - 1.0, TIME[j], TIME[j + 1])


def test_a_rings_swings_give_its_settling_time():
    for decay in (40.0, 55.0, 70.0):
        kept = lobes(TIME, _ring(decay), 0.0)
        assert kept.shape == (LOBES, 4)
        assert settling_times(kept[None], np.zeros(1))[0] == pytest.approx(_settling(decay), abs=1e-7)
        assert np.all(kept[:8, 3] == np.tile([-1.0, 1.0], 4))  # swings alternate sides, the first below rest


def test_between_viscous_rings_the_swings_miss_a_jump_by_at_most_a_swing_where_settling_times_miss_more():
    """Rings of decays 40 to 70 /s every 5 (a family's angles), each swing a factor smaller than the one
    before: between them the last swing to leave the band changes, and the settling time jumps by a half
    period (3.1 ms). The swings, linear between two rings, find the settling time within 0.5 ms at all but
    a few decays between 50 and 60 /s, and within a swing at those (a jump placed a little off); a spline
    of the rings' settling times misses by more."""
    grid = np.arange(40.0, 70.1, 5.0)
    table = np.stack([lobes(TIME, _ring(decay), 0.0) for decay in grid])
    decays = np.linspace(50.0, 60.0, 41)
    found = settling_times(swings_at(table, grid, decays), np.zeros(len(decays)))
    exact = np.array([_settling(decay) for decay in decays])
    error = np.abs(found - exact)
    assert np.max(error) < np.pi / OMEGA + 5e-4 and np.sum(error > 5e-4) <= 2
    ends = settling_times(table, np.zeros(len(grid)))
    assert np.sum(np.abs(CubicSpline(grid, ends)(decays) - exact) > 5e-4) > 2


def test_swings_that_shrink_by_a_step_each_dry_friction_are_found_as_well():
    """A ring under dry friction (the panel's) loses the same height each swing: between two rings the
    swings find the last that leaves the band at every friction, and the settling time within a third
    of a half period."""

    def dry(loss: float) -> np.ndarray:
        swing = np.floor(TIME * OMEGA / np.pi + 0.5)  # the swing each instant belongs to (between zeros)
        return -np.maximum(HEIGHT - 2.0 * loss * swing, 0.0) * np.cos(OMEGA * TIME)

    losses = np.arange(0.6, 1.01, 0.1)
    table = np.stack([lobes(TIME, dry(loss), 0.0) for loss in losses])
    between = np.linspace(0.7, 0.9, 21)
    found = settling_times(swings_at(table, losses, between), np.zeros(len(between)))
    for loss, settling in zip(between, found, strict=True):
        outside = np.flatnonzero(np.abs(dry(loss)) > 1.0)
        assert settling == pytest.approx(TIME[outside[-1]], abs=1e-3), loss  # a third of a half period


def test_a_rest_moved_by_a_load_moves_the_swings_to_first_order():
    """The run judges the ring about the lag held at its first row: a step held at another load rests
    ``shift`` bands off it, and the ring about that rest settles as the swings, moved, say."""
    kept = lobes(TIME, _ring(55.0), 0.0)
    for shift in (-0.05, 0.02, 0.05):
        moved = settling_times(kept[None], np.array([shift]))[0]
        assert moved == pytest.approx(_settling(55.0, shift), abs=1e-4)


def test_a_ring_still_swinging_past_the_swings_kept_is_not_settled():
    kept = lobes(TIME, _ring(5.0), 0.0)  # some hundred swings out of the band
    assert settling_times(kept[None], np.zeros(1))[0] == np.inf
