"""The tolerance tube against an independent checker: LBNL's funnel (``pyfunnel`` on PyPI, its C library),
the regression checker of the Modelica Buildings library.

The same pairs are judged by both with the same tolerances: heliostep's ``Tolerance(abs, rel, time)``
is funnel's ``atoly=abs, ltoly=rel`` (relative to the local value) and ``atolx=time``. Funnel's tube
half-height is ``max(atoly, ltoly*|y|)`` around each reference sample and its half-width ``atolx``;
its envelopes are built through the corners of these rectangles, and its error at a test sample is
``max(0, y - upper) - min(0, y - lower)``: for the pairs below, heliostep's largest excess beyond
the tube equals funnel's largest error (to 1e-12 of the signal's scale), passing and failing alike.

Where the two differ by design (docs/compare.md, "Agreement with funnel"), the tests pin it:
funnel evaluates the tube at the test's samples only, so a reference dip between two samples of a
coarse actual passes funnel and fails heliostep (which checks the reference's samples against the
interpolated actual); funnel refuses traces whose first or last times differ, heliostep accepts an
actual that ends early by less than the time tolerance.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import pyfunnel
import pytest

from heliostep.results.compare.traces import Tolerance, evaluate_signal

T = np.linspace(0.0, 10.0, 201)


def funnel_error(tmp_path, tr, yr, ta, ya, tol: Tolerance) -> float:
    """Funnel's largest error of the test (actual) against the reference, from its errors.csv."""
    out = tmp_path / f"funnel-{len(list(tmp_path.iterdir()))}"
    status = pyfunnel.compareAndReport(
        list(map(float, tr)),
        list(map(float, yr)),
        list(map(float, ta)),
        list(map(float, ya)),
        outputDirectory=str(out),
        atolx=tol.time,
        atoly=tol.abs,
        ltoly=tol.rel,
    )
    assert status == 0
    errors = pd.read_csv(out / "errors.csv")
    assert len(errors) == len(ta)  # one error per test sample
    return float(errors["y"].max())


def _pairs():
    """(label, reference time, reference, actual time, actual, tolerance, expected verdict)."""
    rng = np.random.default_rng(2025)
    y = np.sin(T)
    fine = np.linspace(0.0, 10.0, 1001)
    step_t = np.array([0.0, 1.0, 1.0, 2.0])
    step_y = np.array([0.0, 0.0, 1.0, 1.0])
    tol = Tolerance(abs=0.01, rel=0.0, time=0.05)
    relative = Tolerance(abs=1e-3, rel=0.02, time=0.05)
    yr = 3 * y + 0.2
    return [
        ("identical", T, y, T, y, tol, True),
        ("offset 0.9 abs", T, y, T, y + 0.009, tol, True),
        ("offset 1.1 abs", T, y, T, y + 0.011, tol, False),
        ("finer actual grid", T, y, fine, np.sin(fine), tol, True),
        # a cosine starts flat: a lag inside the time tolerance is inside the tube from the first sample
        ("lag 30 ms", T, np.cos(T), fine, np.cos(fine - 0.03), tol, True),
        ("lag 200 ms", T, np.cos(T), T, np.cos(T - 0.2), tol, False),
        ("step 30 ms late", step_t, step_y, step_t + [0, 0.03, 0.03, 0], step_y, tol, True),
        ("step 70 ms late", step_t, step_y, step_t + [0, 0.07, 0.07, 0], step_y, tol, False),
        ("noise 1 %, rel 2 %", T, yr, T, yr * (1 + rng.uniform(-0.01, 0.01, T.size)), relative, True),
        ("noise 3 %, rel 2 %", T, yr, T, yr * (1 + rng.uniform(-0.03, 0.03, T.size)), relative, False),
    ]


@pytest.mark.parametrize("pair", _pairs(), ids=lambda p: p[0])
def test_heliostep_and_funnel_agree_on_the_verdict_and_the_largest_excess(tmp_path, pair):
    _, tr, yr, ta, ya, tol, expected = pair
    ours = evaluate_signal(ta, ya, tr, yr, tol).result
    theirs = funnel_error(tmp_path, tr, yr, ta, ya, tol)
    assert ours.passed is expected
    assert (theirs == 0.0) is expected
    assert ours.max_excess == pytest.approx(theirs, abs=1e-12 * max(1.0, float(np.abs(yr).max())))


def test_by_design_a_reference_dip_between_coarse_actual_samples_fails_here_and_passes_funnel(tmp_path):
    tr = np.linspace(0.0, 10.0, 1001)
    yr = np.where(np.abs(tr - 5.5) < 0.2, -1.0, 0.0)  # a 0.4 s dip between the actual's samples at 5 and 6 s
    ta = np.linspace(0.0, 10.0, 11)
    ya = np.zeros(ta.size)
    tol = Tolerance(abs=0.01, rel=0.0, time=0.05)
    ours = evaluate_signal(ta, ya, tr, yr, tol).result
    assert not ours.passed and ours.max_excess == pytest.approx(1.0 - 0.01)
    assert 5.3 <= ours.time_max_excess <= 5.7
    assert funnel_error(tmp_path, tr, yr, ta, ya, tol) == 0.0


def test_by_design_funnel_refuses_an_actual_that_ends_early_within_the_time_tolerance(tmp_path):
    tol = Tolerance(abs=0.01, rel=0.0, time=0.1)
    ta = T[:-1]  # ends 0.05 s early
    assert evaluate_signal(ta, np.sin(ta), T, np.sin(T), tol).result.passed
    status = pyfunnel.compareAndReport(
        list(T), list(np.sin(T)), list(ta), list(np.sin(ta)), outputDirectory=str(tmp_path), atolx=0.1, atoly=0.01
    )
    assert status == 1  # "Reference and test data maximum x values are different"
