"""heliostep.drive.sequencer: phase patterns from the torque law, step instants by root finding."""

import numpy as np
from scipy.interpolate import CubicSpline
import pytest
from scipy.optimize import brentq

from heliostep.errors import InputError
from heliostep.drive.sequencer import PATTERNS, Sequencer, reference_interpolant, schedule_steps

N_C = 50  # rotor teeth, Table 3
STEP = np.pi / (2 * N_C)  # 1.8 deg


def stable_position(i_a, i_b, near):
    """Zero of the torque C = -k_e i_a sin(N_c t) - k_e i_b cos(N_c t) ([paper], eq. 9) with dC/dt < 0."""
    torque = lambda t: -i_a * np.sin(N_C * t) - i_b * np.cos(N_C * t)  # noqa: E731
    grid = np.linspace(near - 2.013 * STEP, near + 1.987 * STEP, 400)  # no grid point on a root
    roots = [brentq(torque, a, b) for a, b in zip(grid[:-1], grid[1:]) if torque(a) > 0 > torque(b)]
    return min(roots, key=lambda r: abs(r - near))


@pytest.mark.parametrize("mode", list(PATTERNS))
def test_each_pattern_holds_the_position_the_sequencer_claims(mode):
    sequencer = Sequencer(mode=mode, current=5.5, step_angle=STEP)
    for index in range(-3, 9):
        i_a, i_b = sequencer.reference_currents(index)
        expected = float(sequencer.position(index))
        assert stable_position(i_a, i_b, expected) == pytest.approx(expected, abs=1e-9), (mode, index)


def test_one_phase_on_is_table_1_times_the_current():
    sequencer = Sequencer(current=5.5)
    i_a, i_b = sequencer.reference_currents(np.arange(4))
    assert list(zip(i_a, i_b)) == [(5.5, 0.0), (0.0, -5.5), (-5.5, 0.0), (0.0, 5.5)]


def test_bad_sequencer_settings_are_named():
    with pytest.raises(InputError, match="sequencer mode 'wave': expected one of one-phase-on"):
        Sequencer(mode="wave")
    with pytest.raises(InputError, match="sequencer current"):
        Sequencer(current=0.0)


def test_ramp_steps_exactly_at_half_step_crossings():
    # a reference rotor angle rising at 0.01 rad/s crosses (k + 1/2) * step at t = (k + 1/2) * step / 0.01
    rate = 0.01
    times = np.linspace(0, 60, 61)
    schedule = schedule_steps(reference_interpolant(times, rate * times), Sequencer(step_angle=STEP))
    k = np.arange(len(schedule))
    np.testing.assert_allclose(schedule.times, (k + 0.5) * STEP / rate, rtol=1e-12)
    np.testing.assert_array_equal(schedule.indices, k + 1)
    assert len(schedule) == int(rate * 60 / STEP + 0.5)


def test_reach_trigger_steps_when_the_next_position_is_reached():
    rate = 0.01
    times = np.linspace(0, 60, 61)
    schedule = schedule_steps(reference_interpolant(times, rate * times), Sequencer(step_angle=STEP),
                              trigger="reach")
    k = np.arange(len(schedule))
    np.testing.assert_allclose(schedule.times, (k + 1) * STEP / rate, rtol=1e-12)


def test_reference_that_goes_up_and_down_steps_both_ways_at_the_roots():
    times = np.linspace(0, 100, 2001)
    amplitude = 3.3 * STEP
    reference = reference_interpolant(times, amplitude * np.sin(2 * np.pi * times / 100))
    schedule = schedule_steps(reference, Sequencer(step_angle=STEP))
    # up to +3, down to -3, back to 0: 3 + 6 + 3 steps
    assert list(schedule.indices) == [1, 2, 3, 2, 1, 0, -1, -2, -3, -2, -1, 0]
    # each instant is a true crossing of the half-step level it stands for
    levels = (np.minimum(schedule.indices, np.concatenate([[0], schedule.indices[:-1]])) + 0.5) * STEP
    np.testing.assert_allclose(amplitude * np.sin(2 * np.pi * schedule.times / 100), levels, atol=1e-9)


def test_reference_held_still_makes_no_steps():
    # the reference rises to 0.49 step in 2 s and is then held (the stow 'hold' at sunset): it never
    # reaches the half step, so no step may be commanded. An interpolant that overshoots at the
    # corner would cross 0.5 step and command a spurious step pair: a cubic spline does (checked),
    # the monotone PCHIP the scheduler uses must not.
    times = np.linspace(0, 100, 101)
    held = np.clip(times / 2.0, 0.0, 1.0) * 0.49 * STEP
    fine = np.linspace(0, 100, 100_001)
    assert CubicSpline(times, held)(fine).max() > 0.5 * STEP  # the test can fail: overshoot exists
    assert reference_interpolant(times, held)(fine).max() <= 0.49 * STEP * (1 + 1e-12)
    assert len(schedule_steps(reference_interpolant(times, held), Sequencer(step_angle=STEP))) == 0


def test_index_at_gives_values_before_and_after_a_step():
    times = np.linspace(0, 10, 11)
    schedule = schedule_steps(reference_interpolant(times, 0.01 * times), Sequencer(step_angle=STEP))
    t0 = schedule.times[0]
    assert schedule.index_at(t0, side="left") == 0 and schedule.index_at(t0) == 1
