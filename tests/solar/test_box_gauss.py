"""The closed form of a box * box * Gaussian image's share in a window, row by row.

:func:`heliostep.solar.intercept.box_gauss_fraction` evaluates, for each row, only the closed form
that row takes (a double box, one box, or the Gaussian alone). Checked here against the
convolution integrated numerically in the test (scipy's quad over the trapezoid's density), on
arrays that mix the three kinds, and each row against the same row computed alone.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import quad
from scipy.stats import norm

from heliostep.solar import intercept as ic

HALF_WINDOW = 0.035  # [m] the paper's 70 mm absorber tube, half its diameter


def _share_by_quadrature(centre: float, a: float, b: float, sigma: float, w: float) -> float:
    """P(|c + U(-a, a) + U(-b, b) + N(0, sigma^2)| <= w): the density of U_a + U_b (a trapezoid, a >= b;
    a box when b = 0; a point when both vanish) integrated against the Gaussian's share of the window."""
    window = lambda x: norm.cdf((w - centre - x) / sigma) - norm.cdf((-w - centre - x) / sigma)  # noqa: E731
    if a == 0.0 and b == 0.0:
        return window(0.0)
    if b == 0.0:
        return quad(lambda x: window(x) / (2 * a), -a, a, epsabs=1e-13, points=[-w - centre, w - centre])[0]

    def density(x: float) -> float:  # the convolution of two boxes: flat top of height 1/(2a) on |x| <= a - b
        return min(1.0, max(0.0, (a + b - abs(x)) / (2 * b))) / (2 * a)

    breaks = sorted({-a - b, -a + b, a - b, a + b})
    return sum(quad(lambda x: density(x) * window(x), lo, hi, epsabs=1e-13)[0] for lo, hi in zip(breaks, breaks[1:]))


#: rows of every kind: (centre, a, b, sigma) [m]: two boxes, one box (b negligible), the Gaussian alone
ROWS = [
    (0.0, 0.135, 0.02, 0.01),  # two boxes, the window inside the flat top
    (0.12, 0.135, 0.05, 0.03),  # two boxes, the window on the image's edge
    (-0.2, 0.1, 0.1, 0.02),  # two equal boxes (a triangle), the window off the image
    (0.02, 0.135, 0.0, 0.01),  # one box
    (0.09, 0.05, 1e-12, 0.02),  # one box: b below 1e-4 of a
    (0.01, 0.0, 0.0, 0.01),  # the Gaussian alone
    (0.03, 1e-9, 1e-9, 0.02),  # the Gaussian alone: a below 1e-4 of sigma
]


def test_each_row_of_a_mixed_array_is_its_closed_form_by_quadrature():
    centre, a, b, sigma = (np.array(column) for column in zip(*ROWS))
    shares = ic.box_gauss_fraction(centre, a, b, sigma, HALF_WINDOW)
    expected = [_share_by_quadrature(*row, HALF_WINDOW) for row in ROWS]
    np.testing.assert_allclose(shares, expected, rtol=0, atol=1e-9)
    assert 0.0 < shares.min() and shares.max() < 1.0  # no row at a trivial value


def test_a_row_gives_the_same_bits_alone_as_among_rows_of_other_kinds():
    # the rows of one kind are computed on their own: their bits do not depend on their neighbours
    centre, a, b, sigma = (np.array(column) for column in zip(*ROWS))
    mixed = ic.box_gauss_fraction(centre, a, b, sigma, HALF_WINDOW)
    for k, row in enumerate(ROWS):
        alone = ic.box_gauss_fraction(*(np.array([value]) for value in row), HALF_WINDOW)
        assert alone[0] == mixed[k], ROWS[k]


@pytest.mark.parametrize("b", [0.0, 0.03])
def test_a_scalar_second_box_broadcasts_over_the_rows(b):
    # the secondary concentrator's acceptance passes b = 0.0 as a scalar beside arrays
    centre, a, sigma = np.array([0.0, 0.05, 0.3]), np.array([0.1, 0.0, 0.1]), np.array([0.01, 0.01, 0.02])
    shares = ic.box_gauss_fraction(centre, a, b, sigma, HALF_WINDOW)
    expected = [_share_by_quadrature(c, max(x, b), min(x, b), s, HALF_WINDOW) for c, x, s in zip(centre, a, sigma)]
    np.testing.assert_allclose(shares, expected, rtol=0, atol=1e-9)
