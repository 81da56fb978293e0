"""libcosim as an oracle of fixed-step coupling: heliostep's sampled components against libcosim's
fixed-step algorithm (``libcosimpy``, the test extras) on the same two FMI 2.0 Co-Simulation FMUs.

The system (``tests/support/two_oscillators.py``): a two-mass oscillator split into two instances of the
mini ``Oscillator`` (``tests/data/mini/oscillator.c``, RK4 inside its ``fmi2DoStep``), ``a`` pushed by
``b``'s coupling force, ``b`` reading ``a``'s position and speed. Both masters step both FMUs from t_k
with the inputs of t_k and then pass the outputs on (Jacobi), so at every communication point the
outputs agree to rounding: the step sizes each passes differ in the last bits (heliostep's points are
k h in floating point, libcosim's whole nanoseconds), nothing else. Bound: 1e-12 at every point over
2 s, outputs up to 5 (measured: 1.1e-14 at h = 1 ms, 1.3e-14 at 0.25 ms).
"""

from __future__ import annotations

import numpy as np
import pytest

import two_oscillators

pytest.importorskip("libcosimpy", reason="libcosimpy (libcosim's PyPI package) does not install on this platform")

STOP = 2.0


@pytest.fixture(scope="module")
def fmus(tmp_path_factory):
    return two_oscillators.build(tmp_path_factory.mktemp("oscillators"))


@pytest.mark.parametrize("h", [1e-3, 2.5e-4])
def test_sampled_components_give_libcosims_numbers_at_every_communication_point(fmus, h):
    _, ours_at, ours = two_oscillators.run_heliostep(fmus, h, STOP)
    _, theirs_at, theirs = two_oscillators.run_libcosim(fmus, h, STOP)
    points = round(STOP / h)
    assert len(ours_at) == len(theirs_at) == points
    assert np.max(np.abs(ours_at - theirs_at)) <= 1e-12
    assert np.max(np.abs(ours - theirs)) <= 1e-12
    assert np.max(np.abs(ours), axis=0) == pytest.approx([0.1, 1.14, 0.038, 0.32, 5.1], rel=0.02)  # it moves


def test_two_instances_of_one_fmu_file_run_and_close(fmus):
    """Both instances from one file (one binary loaded twice): the same numbers as from two files, and
    closing the first leaves the second's binary loaded (fmpy's freeInstance unloads it once)."""
    one = {"a": fmus["a"], "b": fmus["a"]}
    _, _, shared = two_oscillators.run_heliostep(one, 1e-3, 0.5)
    _, _, apart = two_oscillators.run_heliostep(fmus, 1e-3, 0.5)
    assert np.array_equal(shared, apart)
