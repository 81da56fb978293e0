"""Tests of heliostep.results.compare.traces: the tolerance-tube comparison.

Expected numbers come from the definition of the tube (worked out by hand in the
comments) or from an independent brute-force evaluation, never from the code.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from scipy.ndimage import maximum_filter1d, minimum_filter1d

from heliostep.errors import InputError
from heliostep.results.compare.traces import (
    ComparisonResult,
    Tolerance,
    ToleranceSet,
    compare_traces,
    evaluate_signal,
    load_tolerances,
)


def trace(t, **signals) -> pd.DataFrame:
    return pd.DataFrame(
        {"time": np.asarray(t, dtype=float), **{k: np.asarray(v, dtype=float) for k, v in signals.items()}}
    )


def step_trace(t_jump: float, grid: np.ndarray, low: float = 0.0, high: float = 1.0) -> pd.DataFrame:
    """Step from *low* to *high* at *t_jump*: two rows at t_jump (value before, value after)."""
    g = grid[grid != t_jump]
    t = np.concatenate([g[g < t_jump], [t_jump, t_jump], g[g > t_jump]])
    y = np.where(t < t_jump, low, high)
    y[np.flatnonzero(t == t_jump)[0]] = low
    return trace(t, s=y)


T1001 = np.linspace(0.0, 10.0, 1001)
T733 = np.linspace(0.0, 10.0, 733)


# --------------------------------------------------------------------------- basics


def test_identical_traces_pass():
    ref = trace(T1001, a=np.sin(T1001), b=np.exp(-T1001))
    result = compare_traces(ref.copy(), ref)
    assert isinstance(result, ComparisonResult)
    assert result.passed
    assert list(result.signals) == ["a", "b"]
    for r in result.signals.values():
        assert r.passed and r.max_excess == 0 and r.max_abs_diff == 0 and r.outside_fraction == 0


def test_identical_traces_pass_with_zero_tolerance():
    ref = step_trace(5.0, T1001)
    assert compare_traces(ref.copy(), ref, Tolerance(abs=0, rel=0, time=0)).passed


def test_perturbation_names_signal_and_time():
    y = np.sin(T1001)
    bumped = y.copy()
    bumped[(T1001 >= 2.0) & (T1001 <= 2.1)] += 0.1
    result = compare_traces(trace(T1001, a=y, b=bumped), trace(T1001, a=y, b=y))
    assert not result.passed
    assert result.failed == ["b"]
    assert result.signals["a"].passed
    b = result.signals["b"]
    assert 2.0 <= b.time_max_excess <= 2.1
    assert 2.0 <= b.time_max_abs_diff <= 2.1
    assert b.max_abs_diff == pytest.approx(0.1)
    # Band at most |sin'| * time_tol + max(abs, rel*|y|) <= 1e-3 + 1e-4 wide.
    assert 0.1 - 1.2e-3 < b.max_excess < 0.1
    # Outside on [2.0, 2.1] plus less than one sample spacing (0.01) of ramp each side,
    # minus at most the time tolerance: between 0.1 s and 0.12 s of 10 s.
    assert 0.01 - 2e-4 < b.outside_fraction < 0.012


def test_to_pandas_summary():
    y = np.sin(T1001)
    result = compare_traces(trace(T1001, a=y, b=y + 1.0), trace(T1001, a=y, b=y))
    table = result.to_pandas()
    assert list(table.index) == ["a", "b"]
    assert table.loc["a", "passed"] and not table.loc["b", "passed"]
    assert table.loc["b", "max_abs_diff"] == pytest.approx(1.0)
    assert table.loc["b", "outside_fraction"] == pytest.approx(1.0)
    for column in ("max_excess", "time_max_excess", "time_max_abs_diff", "abs_tol", "rel_tol", "time_tol"):
        assert column in table.columns


def test_signal_selection_and_defaults():
    ref = trace(T733, a=np.sin(T733), b=np.cos(T733), only_ref=T733)
    act = trace(T733, b=np.cos(T733), a=np.sin(T733), only_act=T733)
    result = compare_traces(act, ref)
    assert list(result.signals) == ["a", "b"]  # reference order, common signals only
    assert result.only_in_actual == ("only_act",)
    assert result.only_in_reference == ("only_ref",)
    assert list(compare_traces(act, ref, signals=["b"]).signals) == ["b"]


# --------------------------------------------------------------------------- tube definition


def test_value_band_is_max_of_abs_and_rel_not_sum():
    # Reference 100, abs 1e-3, rel 1e-4: half-width max(1e-3, 1e-2) = 1e-2
    # (the sum would be 1.1e-2).
    t = np.linspace(0.0, 1.0, 11)
    tol = Tolerance(abs=1e-3, rel=1e-4, time=0.0)
    ref = trace(t, x=np.full(11, 100.0))
    assert compare_traces(trace(t, x=np.full(11, 100.009)), ref, tol).passed
    below = compare_traces(trace(t, x=np.full(11, 99.991)), ref, tol)
    assert below.passed
    beyond = compare_traces(trace(t, x=np.full(11, 100.0105)), ref, tol).signals["x"]
    assert not beyond.passed
    assert beyond.max_excess == pytest.approx(0.0005, abs=1e-9)
    assert beyond.outside_fraction == pytest.approx(1.0)
    # Near zero the absolute tolerance rules: reference 0, actual 9e-4 passes, 1.1e-3 fails.
    zero = trace(t, x=np.zeros(11))
    assert compare_traces(trace(t, x=np.full(11, 9e-4)), zero, tol).passed
    assert not compare_traces(trace(t, x=np.full(11, 1.1e-3)), zero, tol).passed


def test_time_tolerance_widens_a_ramp():
    # Reference y = max(t - 0.2, 0); the actual is the same delayed by 0.05 s.
    t = np.linspace(0.0, 1.0, 101)
    ref, act = trace(t, y=np.maximum(t - 0.2, 0)), trace(t, y=np.maximum(t - 0.25, 0))
    late = compare_traces(act, ref, Tolerance(abs=1e-6, rel=0, time=0.06))
    assert late.passed
    result = compare_traces(act, ref, Tolerance(abs=1e-6, rel=0, time=0.04)).signals["y"]
    # For t >= 0.25 the lower bound is t - 0.2 - 0.04 - 1e-6, the actual t - 0.25.
    assert not result.passed
    assert result.max_excess == pytest.approx(0.01 - 1e-6, rel=1e-6)
    # Outside where the actual is below max(t - 0.24, 0) - 1e-6: for t in [0.2, 0.25]
    # the actual is 0, so from t = 0.240001 on; for t >= 0.25 always. That is
    # 0.759999 s of 1 s.
    assert result.outside_fraction == pytest.approx(0.759999, rel=1e-6)


@pytest.mark.parametrize("shift", [0.0004, -0.0009])
def test_step_shifted_less_than_time_tolerance_passes(shift):
    ref = step_trace(5.0, T1001)
    act = step_trace(5.0 + shift, T733)
    result = compare_traces(act, ref, Tolerance(abs=1e-6, rel=0.0, time=1e-3))
    assert result.passed


@pytest.mark.parametrize("shift", [0.0015, -0.002])
def test_step_shifted_more_than_time_tolerance_fails(shift):
    ref = step_trace(5.0, T1001)
    act = step_trace(5.0 + shift, T733)
    r = compare_traces(act, ref, Tolerance(abs=1e-6, rel=0.0, time=1e-3)).signals["s"]
    assert not r.passed
    # The actual is on the wrong side of the step for |shift| - time_tol seconds.
    lo, hi = sorted([5.0, 5.0 + shift])
    assert lo <= r.time_max_excess <= hi
    assert r.max_excess == pytest.approx(1.0 - 1e-6)
    assert r.outside_fraction * 10.0 == pytest.approx(abs(shift) - 1e-3, rel=1e-6)


def test_jump_is_not_blurred_by_interpolation():
    # The same step on two grids, zero time tolerance: interpolating across the
    # jump would put ramps of 0.01 s and 0.0137 s in the two traces.
    ref = step_trace(5.0, T1001, low=-2.0, high=3.0)
    act = step_trace(5.0, T733, low=-2.0, high=3.0)
    assert compare_traces(act, ref, Tolerance(abs=1e-9, rel=0, time=0)).passed
    # A step that jumps to a different value fails right after the jump.
    wrong = step_trace(5.0, T733, low=-2.0, high=3.1)
    r = compare_traces(wrong, ref, Tolerance(abs=1e-9, rel=0, time=0)).signals["s"]
    assert not r.passed and 5.0 <= r.time_max_excess <= 10.0
    assert r.max_excess == pytest.approx(0.1 - 1e-9)
    assert r.outside_fraction == pytest.approx(0.5)  # from the jump at 5 s to the end


def test_same_analytic_signal_on_different_grids():
    ref = trace(T1001, s=np.sin(T1001))
    act = trace(T733, s=np.sin(T733))
    # Linear interpolation error of sin on spacing h is at most h^2/8:
    # (10/732)^2/8 = 2.3e-5 for the coarse grid, so the polylines differ by less
    # than 1e-4 everywhere.
    assert compare_traces(act, ref, Tolerance(abs=1e-4, rel=0, time=0)).passed
    # ... but by more than 1e-6 near the extrema (about 2.3e-5 - 1.25e-5).
    assert not compare_traces(act, ref, Tolerance(abs=1e-6, rel=0, time=0)).passed
    # The default tolerance accepts the grid change.
    assert compare_traces(act, ref).passed


def test_narrow_spike_only_in_actual_fails():
    # Reference zero on a 0.01 s grid; the actual has a 2 ms wide spike between
    # two reference samples (3.452 .. 3.456).
    t = np.linspace(0.0, 10.0, 1001)
    ref = trace(t, s=np.zeros_like(t))
    ta = np.sort(np.r_[t, 3.453, 3.454, 3.455])
    ya = np.where(ta == 3.454, 1.0, 0.0)
    r = compare_traces(trace(ta, s=ya), ref, Tolerance(abs=1e-3, rel=0, time=1e-3)).signals["s"]
    assert not r.passed
    assert r.time_max_excess == pytest.approx(3.454)
    assert r.max_excess == pytest.approx(1.0 - 1e-3)
    # Above 1e-3 between 3.453001 and 3.454999: almost 2 ms of 10 s.
    assert r.outside_fraction == pytest.approx(0.002 * (1 - 1e-3) / 10.0, rel=1e-6)


def test_spike_only_in_reference():
    # The reference has a 2 ms spike between two actual samples. The actual is
    # evaluated at the reference's points, so the tube's narrowing there is seen.
    t = np.linspace(0.0, 10.0, 1001)
    tr = np.sort(np.r_[t, 3.453, 3.454, 3.455])
    ref = trace(tr, s=np.where(tr == 3.454, 1.0, 0.0))
    act = trace(t, s=np.zeros_like(t))
    # Time tolerance 0.5 ms < half the spike width: at t = 3.454 the lower bound is
    # min over [3.4535, 3.4545] of the spike = 0.5; the actual (0) is below it.
    r = compare_traces(act, ref, Tolerance(abs=1e-3, rel=0, time=5e-4)).signals["s"]
    assert not r.passed
    assert r.time_max_excess == pytest.approx(3.454)
    assert r.max_excess == pytest.approx(0.5 - 1e-3)
    # With a time tolerance wider than the spike the tube always reaches down to 0:
    # a feature narrower than the time tolerance may be missing (tube semantics).
    assert compare_traces(act, ref, Tolerance(abs=1e-3, rel=0, time=2e-3)).passed


def test_violation_between_all_grid_points_is_found():
    # Reference V: (-1, 2), (0, 0), (1, 1); time tolerance 0.3, abs 0.01.
    # For t in [-0.3, 0.3] the upper bound is max(-2(t - 0.3), t + 0.3) + 0.01,
    # lowest at t = 0.1 (0.41). The actual (-1, 2), (-0.3, 0.55), (0.3, 0.55), (1, 1)
    # is inside at every sample of both traces and at every sample +- 0.3, but
    # above the tube on (0.03, 0.24) by up to 0.55 - 0.41 = 0.14 at t = 0.1.
    ref = trace([-1.0, 0.0, 1.0], v=[2.0, 0.0, 1.0])
    act = trace([-1.0, -0.3, 0.3, 1.0], v=[2.0, 0.55, 0.55, 1.0])
    r = compare_traces(act, ref, Tolerance(abs=0.01, rel=0, time=0.3)).signals["v"]
    assert not r.passed
    assert r.max_excess == pytest.approx(0.14)
    assert r.time_max_excess == pytest.approx(0.1)
    assert r.outside_fraction == pytest.approx(0.21 / 2.0)
    # Lowering the actual to 0.40 (below 0.41) makes it pass.
    act_ok = trace([-1.0, -0.3, 0.3, 1.0], v=[2.0, 0.40, 0.40, 1.0])
    assert compare_traces(act_ok, ref, Tolerance(abs=0.01, rel=0, time=0.3)).passed


def test_rows_between_the_limits_of_a_jump_are_checked():
    # Event iteration: three rows at t = 1; the middle one (5.0) is outside.
    ref = trace([0.0, 1.0, 1.0, 2.0], s=[0.0, 0.0, 1.0, 1.0])
    glitch = trace([0.0, 1.0, 1.0, 1.0, 2.0], s=[0.0, 0.0, 5.0, 1.0, 1.0])
    r = compare_traces(glitch, ref).signals["s"]
    assert not r.passed and r.time_max_excess == 1.0
    assert r.max_excess == pytest.approx(4.0 - 1e-4)  # 5 - (1 + max(1e-6, 1e-4 * 1))
    between = trace([0.0, 1.0, 1.0, 1.0, 2.0], s=[0.0, 0.0, 0.5, 1.0, 1.0])
    assert compare_traces(between, ref).passed


def test_truncated_actual_fails_with_a_note():
    t = np.linspace(0.0, 10.0, 101)
    ref = trace(t, s=np.sin(t))
    act = trace(t[:61], s=np.sin(t[:61]))  # stops at 6 s
    r = compare_traces(act, ref).signals["s"]
    assert not r.passed
    assert "reference [0, 10]" in r.note
    assert r.outside_fraction == pytest.approx(0.4)


def test_actual_longer_than_reference_is_compared_on_the_reference_span():
    t = np.linspace(0.0, 10.0, 101)
    ref = trace(t[:51], s=np.sin(t[:51]))
    act = trace(t, s=np.where(t > 5.0, 100.0, np.sin(t)))
    assert compare_traces(act, ref).passed


def _brute_force(ta, ya, tr, yr, tol: Tolerance, n=200_001):
    """The tube's definition on a fine uniform grid (ignoring jumps' zero-width instants)."""
    s = np.linspace(tr[0], tr[-1], n)
    ds = s[1] - s[0]
    # Left limits at every fine point (np.interp takes the last of duplicates: use reversed).
    ref = np.interp(s, tr, yr)
    h = np.maximum(tol.abs, tol.rel * np.abs(ref))
    w = 2 * int(round(tol.time / ds)) + 1
    upper = maximum_filter1d(ref + h, size=w, mode="nearest")
    lower = minimum_filter1d(ref - h, size=w, mode="nearest")
    act = np.interp(s, ta, ya)
    excess = np.maximum(act - upper, lower - act)
    return excess.max(), s[np.argmax(excess)], np.mean(excess > 0)


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_agrees_with_brute_force_on_random_polylines(seed):
    rng = np.random.default_rng(seed)
    tr = np.sort(rng.uniform(0, 10, 40))
    tr[0], tr[-1] = 0.0, 10.0
    yr = np.cumsum(rng.normal(0, 1, tr.size))
    ta = np.sort(rng.uniform(0, 10, 55))
    ta[0], ta[-1] = 0.0, 10.0
    ya = np.interp(ta, tr, yr) + rng.normal(0, 0.3, ta.size)
    tol = Tolerance(abs=0.05, rel=0.02, time=0.2)
    r = evaluate_signal(ta, ya, tr, yr, tol).result
    excess, _, fraction = _brute_force(ta, ya, tr, yr, tol)
    assert excess > 0  # the random actual leaves the tube somewhere
    # The fine grid (spacing 5e-5 s, slopes well below 1e3) under-estimates slightly.
    assert r.max_excess == pytest.approx(excess, abs=5e-3)
    assert r.outside_fraction == pytest.approx(fraction, abs=2e-3)


def test_large_trace_finds_a_single_bad_sample():
    n = 100_000
    t = np.linspace(0.0, 1000.0, n)
    ref = trace(t, a=np.sin(t), b=np.cos(t))
    y = np.cos(t)
    y[77_777] += 0.01
    result = compare_traces(trace(t, a=np.sin(t), b=y), ref)
    assert result.signals["a"].passed
    assert not result.signals["b"].passed
    assert result.signals["b"].time_max_excess == pytest.approx(t[77_777])


# --------------------------------------------------------------------------- tolerances


def test_tolerance_set_per_signal_overrides():
    tols = ToleranceSet(Tolerance(abs=1e-6, rel=0, time=0), {"a": {"abs": 0.2}})
    assert tols.for_signal("a") == Tolerance(abs=0.2, rel=0, time=0)
    assert tols.for_signal("b") == Tolerance(abs=1e-6, rel=0, time=0)
    t = np.linspace(0, 1, 11)
    ref = trace(t, a=t, b=t)
    result = compare_traces(trace(t, a=t + 0.1, b=t + 0.1), ref, tols)
    assert result.signals["a"].passed and not result.signals["b"].passed
    assert tols.with_default(abs=0.5).for_signal("b").abs == 0.5
    assert tols.with_default(abs=0.5).for_signal("a").abs == 0.2


def test_load_tolerances(tmp_path):
    path = tmp_path / "tol.yaml"
    path.write_text("default: {abs: 1e-6, rel: 1e-4, time: 1e-3}\nsignals:\n  motor.tau: {abs: 1e-3}\n")
    tols = load_tolerances(path)
    assert tols.default == Tolerance(abs=1e-6, rel=1e-4, time=1e-3)
    assert tols.for_signal("motor.tau") == Tolerance(abs=1e-3, rel=1e-4, time=1e-3)
    empty = tmp_path / "empty.yaml"
    empty.write_text("")
    assert load_tolerances(empty) == ToleranceSet()


def test_a_scenario_section_overrides_the_signals_for_that_scenario_only(tmp_path):
    path = tmp_path / "tol.yaml"
    path.write_text(
        "default: {abs: 1e-6, rel: 0, time: 0}\nsignals:\n  motor.tau: {abs: 1e-3, rel: 1e-4}\n"
        "scenarios:\n  weak:\n    signals:\n      motor.tau: {abs: 0.5}\n      motor.i_a: {time: 2e-3}\n"
    )
    tols = load_tolerances(path)
    assert tols.for_signal("motor.tau") == Tolerance(abs=1e-3, rel=1e-4, time=0)
    weak = tols.for_scenario("weak")
    assert weak.for_signal("motor.tau") == Tolerance(abs=0.5, rel=1e-4, time=0)  # rel from signals, abs its own
    assert weak.for_signal("motor.i_a") == Tolerance(abs=1e-6, rel=0, time=2e-3)
    assert tols.for_scenario("other").for_signal("motor.tau") == tols.for_signal("motor.tau")


@pytest.mark.parametrize(
    ("text", "key"),
    [
        ("default: {abss: 1}\n", "abss"),
        ("signals: {motor.tau: {atol: 1}}\n", "atol"),
        ("defaults: {abs: 1}\n", "defaults"),
        ("scenarios: {weak: {signals: {motor.tau: {absolute: 1}}}}\n", "absolute"),
    ],
)
def test_unknown_tolerance_keys_are_named(tmp_path, text, key):
    path = tmp_path / "tol.yaml"
    path.write_text(text)
    with pytest.raises(InputError, match=rf"tol\.yaml: unknown key '{key}'"):
        load_tolerances(path)


@pytest.mark.parametrize("text", ["default: {abs: -1}\n", "default: {rel: x}\n", "default: {time: .nan}\n", "[1, 2]\n"])
def test_bad_tolerance_values(tmp_path, text):
    path = tmp_path / "tol.yaml"
    path.write_text(text)
    with pytest.raises(InputError, match=r"tol\.yaml"):
        load_tolerances(path)


@pytest.mark.parametrize("field", ["abs", "rel", "time"])
def test_negative_tolerance_is_refused(field):
    with pytest.raises(InputError, match=field):
        Tolerance(**{field: -1.0})


# --------------------------------------------------------------------------- bad input


def test_missing_signal_names_trace_and_column():
    t = np.linspace(0, 1, 5)
    with pytest.raises(InputError, match=r"ref\.csv: no column 'b'"):
        compare_traces(trace(t, a=t, b=t), trace(t, a=t), signals=["a", "b"], reference_name="ref.csv")
    with pytest.raises(InputError, match="no signal in common"):
        compare_traces(trace(t, a=t), trace(t, b=t))


def test_nan_names_trace_and_column():
    t = np.linspace(0, 1, 5)
    y = t.copy()
    y[3] = np.nan
    with pytest.raises(InputError, match=r"act\.parquet: column 'a' has NaN in data row 4 \(time 0\.75 s\)"):
        compare_traces(trace(t, a=y), trace(t, a=t), actual_name="act.parquet")


def test_bad_time_column():
    t = np.linspace(0, 1, 5)
    with pytest.raises(InputError, match=r"reference: no 'time' column"):
        compare_traces(trace(t, a=t), pd.DataFrame({"t": t, "a": t}))
    with pytest.raises(InputError, match=r"actual: column 'time' decreases"):
        compare_traces(trace(t[::-1], a=t), trace(t, a=t))
    with pytest.raises(InputError, match=r"actual: no rows"):
        compare_traces(trace([], a=[]), trace(t, a=t))
