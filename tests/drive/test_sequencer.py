"""heliostep.drive.sequencer: phase patterns from the torque law, step instants by root finding."""

import numpy as np
import pytest
from scipy.interpolate import CubicSpline
from scipy.optimize import brentq

from heliostep.drive.sequencer import (
    PATTERNS,
    TRIGGERS,
    PreparationStopped,
    Sequencer,
    reference_interpolant,
    schedule_steps,
)
from heliostep.errors import InputError

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
    schedule = schedule_steps(reference_interpolant(times, rate * times), Sequencer(step_angle=STEP), trigger="reach")
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


# --------------------------------------------------------------------------- microstepping, idle current
from heliostep.drive.sequencer import (  # noqa: E402
    StepSchedule,  # noqa: E402
    holding_energy,
    idle_currents,
)

R_PHASE = 0.1  # [ohm], Table 3


@pytest.mark.parametrize("microsteps", [2, 4, 8, 16])
def test_microstep_currents_hold_the_position_the_sequencer_claims(microsteps):
    sequencer = Sequencer(current=5.5, step_angle=STEP, microsteps=microsteps)
    for index in range(-3, 2 * microsteps + 3):
        i_a, i_b = sequencer.reference_currents(index)
        assert np.hypot(i_a, i_b) == pytest.approx(5.5)  # sine/cosine: constant current magnitude
        expected = index * STEP / microsteps
        assert stable_position(i_a, i_b, expected) == pytest.approx(expected, abs=1e-9)
    # every N-th microstep is a one-phase-on full step (Table 1)
    full = Sequencer(current=5.5, step_angle=STEP)
    for k in range(4):
        np.testing.assert_allclose(sequencer.reference_currents(k * microsteps), full.reference_currents(k), atol=1e-12)


@pytest.mark.parametrize("microsteps", [1, 2, 4, 8, 16])
def test_microstep_schedule_scales_with_the_microstep(microsteps):
    rate = 3 * STEP / 100.0  # [rad/s], a ramp of 3 full steps in 100 s
    t = np.linspace(0.0, 100.0, 201)
    sequencer = Sequencer(current=5.5, step_angle=STEP, microsteps=microsteps)
    schedule = schedule_steps(reference_interpolant(t, rate * t), sequencer)
    increment = STEP / microsteps
    n = len(schedule)
    assert n == 3 * microsteps
    # midpoint trigger: step k at (k - 1/2) increments of the ramp
    np.testing.assert_allclose(schedule.times, (np.arange(1, n + 1) - 0.5) * increment / rate, rtol=1e-9)
    np.testing.assert_allclose(sequencer.position(schedule.indices), np.arange(1, n + 1) * increment, rtol=1e-12)
    # the tracking error bound (reference minus commanded position) is half the microstep
    probe = np.linspace(0.0, 100.0, 20001)
    error = rate * probe - sequencer.position(schedule.index_at(probe))
    assert np.max(np.abs(error)) == pytest.approx(increment / 2, rel=1e-3)


def test_microsteps_need_one_phase_on_and_a_driver_division():
    with pytest.raises(InputError, match="microsteps"):
        Sequencer(mode="half-step", microsteps=4)
    with pytest.raises(InputError, match="microsteps"):
        Sequencer(microsteps=3)
    with pytest.raises(InputError, match="idle_current_fraction"):
        Sequencer(idle_current_fraction=0.0)


@pytest.mark.parametrize("fraction", [0.25, 0.5, 0.7, 1.0])
@pytest.mark.parametrize("microsteps", [1, 8])
def test_idle_reduction_cuts_holding_energy_by_the_square(fraction, microsteps):
    schedule = StepSchedule(times=np.array([10.0, 25.0, 60.0]), indices=np.array([1, 2, 3]), initial_index=0)
    end, delay, current = 100.0, 0.5, 5.5
    full = Sequencer(current=current, step_angle=STEP, microsteps=microsteps)
    idle = Sequencer(
        current=current, step_angle=STEP, microsteps=microsteps, idle_current_fraction=fraction, idle_delay=delay
    )
    times, i_a, i_b = idle_currents(schedule, idle, end)
    # full current for `delay` after the start and each step, f * I for the rest: R (f I)^2 per phase
    assert np.all(np.hypot(i_a, i_b)[np.isin(times, [0.0, 10.0, 25.0, 60.0])] == pytest.approx(current))
    held = 4 * delay
    expected = R_PHASE * current**2 * (held + fraction**2 * (end - held))
    assert holding_energy(times, i_a, i_b, end, R_PHASE) == pytest.approx(expected, rel=1e-12)
    # with no delay the whole holding energy scales with f^2
    zero = Sequencer(current=current, step_angle=STEP, microsteps=microsteps, idle_current_fraction=fraction)
    e_full = holding_energy(*idle_currents(schedule, full, end), end, R_PHASE)
    e_idle = holding_energy(*idle_currents(schedule, zero, end), end, R_PHASE)
    assert e_full == pytest.approx(R_PHASE * current**2 * end)
    assert e_idle / e_full == pytest.approx(fraction**2, rel=1e-12)


def _walk_by_whole_spline_roots(reference, sequencer, fraction=0.5):
    """The schedule the long way: at each step, every root of the whole spline (scipy's public
    ``PPoly.solve``) at the two trigger levels, the direction from the slope's sign, the first after t."""
    start, stop = reference.x[0], reference.x[-1]
    slope = reference.derivative()
    index = sequencer.nearest_index(float(reference(start)))
    t, times, indices = start, [], []
    while True:
        position = float(sequencer.position(index))
        found = []
        for level, direction in (
            (position + fraction * sequencer.increment, 1),
            (position - fraction * sequencer.increment, -1),
        ):
            roots = [r for r in reference.solve(level, extrapolate=False) if np.isfinite(r) and start < r <= stop]
            later = [r for r in roots if r > t and np.sign(slope(r)) == direction]
            found.append(min(later) if later else np.inf)
        if not np.isfinite(min(found)):
            return np.array(times), np.array(indices)
        t, index = (found[0], index + 1) if found[0] <= found[1] else (found[1], index - 1)
        times.append(t)
        indices.append(index)


def _swing(held: bool):
    """A reference that rises, turns and falls over 600 pieces (a sun-like swing with a wobble); ``held``: with
    stretches held still (zero slope at their knots) and a plateau at the top."""
    times = np.linspace(0.0, 600.0, 601)
    angle = 0.4 * np.sin(times / 200.0) + 0.002 * np.sin(times / 7.0)
    if held:
        angle = np.minimum(angle, 0.39)
        for begin in (40, 170, 500):
            angle[begin : begin + 12] = angle[begin]
    return reference_interpolant(times, angle)


def _exact_crossings(reference, times, levels):
    """The crossing of each level near each time, by Newton's steps on the piece in long double (the cubic as
    stored, its root to beyond double precision)."""
    piece = np.searchsorted(reference.x, times, side="left") - 1
    c = reference.c[:, piece].astype(np.longdouble)
    start = reference.x[piece].astype(np.longdouble)
    s = np.asarray(times, dtype=np.longdouble) - start
    for _ in range(8):
        value = ((c[0] * s + c[1]) * s + c[2]) * s + c[3] - np.asarray(levels, dtype=np.longdouble)
        s -= value / ((3 * c[0] * s + 2 * c[1]) * s + c[2])
    return start + s


@pytest.mark.parametrize("held", [False, True], ids=["moving", "held stretches"])
@pytest.mark.parametrize("trigger", ["midpoint", "reach"])
def test_the_schedule_is_the_whole_spline_roots(held, trigger):
    """The schedule of a reference stepping both ways is the long way's: the same steps, at the same roots to
    within scipy's rounding (its roots, eigenvalues of the companion matrix, are a few floats off), each as near
    the cubic's exact root as the rounding of its value allows (a few eps of the level over the slope, and half a
    float's spacing), for both triggers."""
    reference = _swing(held)
    sequencer = Sequencer(step_angle=STEP / 4)
    fraction = TRIGGERS[trigger]
    schedule = schedule_steps(reference, sequencer, trigger=trigger)
    expected_times, expected_indices = _walk_by_whole_spline_roots(reference, sequencer, fraction)
    assert len(schedule) > 80 and np.any(np.diff(schedule.indices) < 0)  # it steps both ways
    assert np.array_equal(schedule.indices, expected_indices)
    spacing = np.spacing(expected_times)
    assert np.all(np.abs(schedule.times - expected_times) <= 8 * spacing)
    before = np.concatenate([[schedule.initial_index], schedule.indices[:-1]])
    levels = sequencer.position(before) + fraction * sequencer.increment * np.sign(schedule.indices - before)
    exact = _exact_crossings(reference, schedule.times, levels)
    conditioned = 4 * np.finfo(float).eps * np.abs(levels) / np.abs(reference.derivative()(schedule.times))
    assert np.all(np.abs(schedule.times - exact) <= 0.5 * spacing + conditioned)


def test_a_stop_request_stops_the_scheduling():
    """A stop request is looked at while the levels are solved and while the steps are walked: asked to stop at
    its first look or its last, the scheduler raises; never asked to, it schedules what it would without."""
    times = np.linspace(0.0, 3000.0, 301)
    reference = reference_interpolant(times, 0.01 * STEP * times)  # 3000 / 100 * 100 = 3000 quarter steps
    sequencer = Sequencer(step_angle=STEP / 100)
    asked = []
    schedule = schedule_steps(reference, sequencer, should_stop=lambda: asked.append(1) and False)
    assert len(schedule) == 3000 and len(asked) >= 2
    assert np.array_equal(schedule.times, schedule_steps(reference, sequencer).times)
    with pytest.raises(PreparationStopped, match="solving the step levels"):
        schedule_steps(reference, sequencer, should_stop=lambda: True)
    looks = []
    with pytest.raises(PreparationStopped, match="scheduling the steps"):
        schedule_steps(reference, sequencer, should_stop=lambda: looks.append(1) or len(looks) == len(asked))
