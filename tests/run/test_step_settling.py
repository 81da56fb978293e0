"""A step's settling time from the swings of its ring (heliostep.run.step_settling) against a damped
oscillation written here, whose settling time is the last root of |x(t)| = 1 band, found by brentq."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import brentq

from heliostep.run.step_settling import LOBES, lobes, settling_times

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
        settling = settling_times(kept[None], kept[None], np.zeros(1), np.zeros(1))[0]
        assert settling == pytest.approx(_settling(decay), abs=1e-7)
        assert np.all(kept[:8, 3] == np.tile([-1.0, 1.0], 4))  # swings alternate sides, the first below rest


def test_between_two_rings_the_swings_find_the_settling_time_where_the_settling_times_do_not():
    """Between decays 50 and 60 /s the last swing to leave the band changes (the settling time jumps by a
    half period): interpolating the two settling times misses that; the swings' heights, smooth in the
    decay, find it within a thousandth of a second at every decay between."""
    low, high = lobes(TIME, _ring(50.0), 0.0), lobes(TIME, _ring(60.0), 0.0)
    ends = settling_times(np.stack([low, high]), np.stack([low, high]), np.zeros(2), np.zeros(2))
    assert ends[0] - ends[1] > 0.5 * np.pi / OMEGA  # a jump lies between them
    decays = np.linspace(50.0, 60.0, 21)
    weight = (decays - 50.0) / 10.0
    found = settling_times(np.repeat(low[None], 21, 0), np.repeat(high[None], 21, 0), weight, np.zeros(21))
    exact = np.array([_settling(decay) for decay in decays])
    assert np.max(np.abs(found - exact)) < 1e-3
    assert np.max(np.abs(ends[0] + weight * (ends[1] - ends[0]) - exact)) > 1e-3


def test_a_rest_moved_by_a_load_moves_the_swings_to_first_order():
    """The run judges the ring about the lag held at its first row: a step held at another load rests
    ``shift`` bands off it, and the ring about that rest settles as the swings, moved, say."""
    kept = lobes(TIME, _ring(55.0), 0.0)
    for shift in (-0.05, 0.02, 0.05):
        moved = settling_times(kept[None], kept[None], np.zeros(1), np.array([shift]))[0]
        assert moved == pytest.approx(_settling(55.0, shift), abs=1e-4)


def test_a_ring_still_swinging_past_the_swings_kept_is_not_settled():
    kept = lobes(TIME, _ring(5.0), 0.0)  # some hundred swings out of the band
    assert settling_times(kept[None], kept[None], np.zeros(1), np.zeros(1))[0] == np.inf
