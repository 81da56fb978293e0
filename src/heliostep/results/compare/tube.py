"""The tolerance tube around a reference signal and the numerics of checking a trace against it.

Interpolation that never crosses a jump (:func:`interp_at`), window maxima by a sparse table
(:class:`RangeMax`), the tube's bounds (:class:`Tube`) and where a bound changes its piece
(:meth:`Tube.breakpoints`); the method: docs/compare.md.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np

from heliostep.results.compare.tolerance import Tolerance

__all__ = [
    "WINDOW_FIELDS",
    "RangeMax",
    "Side",
    "Tube",
    "Window",
    "group_middle",
    "interp",
    "interp_at",
    "positive_fraction",
]

#: Which limit of a polyline at a time: just before it (``"left"``) or just after it (``"right"``).
Side = Literal["left", "right"]


def interp_at(t: np.ndarray, y: np.ndarray, x: np.ndarray, idx: np.ndarray, side: Side) -> np.ndarray:
    """Value of the polyline (t, y) at *x*: its left limit (``side="left"``) or right limit.

    *idx* must be ``np.searchsorted(t, x, side=side)``. At a time with several
    samples the left limit is the first, the right limit the last of them;
    interpolation only runs between samples with distinct times, so it never blurs
    a jump. Outside ``[t[0], t[-1]]`` the end value is held.
    """
    n = t.size
    if side == "right":
        i = np.clip(idx - 1, 0, n - 1)
        j = np.minimum(i + 1, n - 1)
    else:
        j = np.clip(idx, 0, n - 1)
        i = np.maximum(j - 1, 0)
    ti = t[i]
    dt = t[j] - ti
    with np.errstate(divide="ignore", invalid="ignore"):
        f = (x - ti) / dt
    f[~(dt > 0)] = 0.0
    np.clip(f, 0.0, 1.0, out=f)
    return (1.0 - f) * y[i] + f * y[j]


def interp(t: np.ndarray, y: np.ndarray, x: np.ndarray, side: Side) -> np.ndarray:
    """Like :func:`interp_at`, locating *x* itself."""
    return interp_at(t, y, x, np.searchsorted(t, x, side=side), side)


class RangeMax:
    """Sparse table: maximum of ``values[lo:hi]`` in O(1) per query after O(n log n) setup."""

    def __init__(self, values: np.ndarray) -> None:
        n = values.size
        levels = max(1, n.bit_length())
        table = np.full((levels, n), -np.inf)
        table[0] = values
        for k in range(1, levels):
            width = 1 << k
            half = width >> 1
            m = n - width + 1
            table[k, :m] = np.maximum(table[k - 1, :m], table[k - 1, half : half + m])
        self._table = table

    def query(self, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
        """Maximum over ``[lo, hi)`` element-wise; ``-inf`` where the range is empty."""
        length = hi - lo
        valid = length > 0
        k = np.frexp(np.where(valid, length, 1).astype(np.float64))[1] - 1
        n = self._table.shape[1]
        a = self._table[k, np.clip(lo, 0, n - 1)]
        b = self._table[k, np.clip(hi - (1 << k), 0, n - 1)]
        return np.where(valid, np.maximum(a, b), -np.inf)


@dataclass(frozen=True)
class Window:
    """Query times *x* with the window ends ``x -+ tau`` located in the reference times."""

    x: np.ndarray
    a: np.ndarray  # x - tau
    b: np.ndarray  # x + tau
    a_left: np.ndarray  # searchsorted(t, a, "left"), ...
    a_right: np.ndarray
    b_left: np.ndarray
    b_right: np.ndarray


WINDOW_FIELDS = ("x", "a", "b", "a_left", "a_right", "b_left", "b_right")


class Tube:
    """The tolerance tube around one reference signal (see :mod:`heliostep.results.compare.traces`)."""

    def __init__(self, t: np.ndarray, y: np.ndarray, tol: Tolerance) -> None:
        self.tol = tol
        self.tau = tol.time
        self.t, self.y = self._insert_kinks(t, y, tol)
        h = tol.half_width(self.y)
        self._hi = RangeMax(self.y + h)
        self._lo_neg = RangeMax(h - self.y)  # max of -(y - h)

    @staticmethod
    def _insert_kinks(t: np.ndarray, y: np.ndarray, tol: Tolerance) -> tuple[np.ndarray, np.ndarray]:
        """Add vertices where ``|y|`` crosses ``abs/rel``, so ``y +- h(y)`` is linear per segment."""
        if tol.rel <= 0 or t.size < 2:
            return t, y
        c = tol.abs / tol.rel
        y0, y1 = y[:-1], y[1:]
        seg = np.flatnonzero(t[1:] > t[:-1])
        new_key, new_t, new_y = [], [], []
        for level in np.unique([-c, c]):
            hit = seg[(y0[seg] - level) * (y1[seg] - level) < 0]
            if not hit.size:
                continue
            frac = (level - y0[hit]) / (y1[hit] - y0[hit])
            new_key.append(hit + frac)
            new_t.append(t[hit] + frac * (t[hit + 1] - t[hit]))
            new_y.append(np.full(hit.size, level))
        if not new_key:
            return t, y
        keys = np.concatenate([np.arange(t.size, dtype=np.float64), *new_key])
        order = np.argsort(keys, kind="stable")
        tt = np.concatenate([t, *new_t])[order]
        yy = np.concatenate([y, *new_y])[order]
        # Rounding may put an inserted time a hair outside its segment: keep t sorted.
        return np.maximum.accumulate(tt), yy

    def _g(self, values: np.ndarray, upper: bool) -> np.ndarray:
        h = self.tol.half_width(values)
        return values + h if upper else values - h

    def window(self, x: np.ndarray) -> Window:
        t = self.t
        a, b = x - self.tau, x + self.tau
        a_left, a_right = np.searchsorted(t, a, "left"), np.searchsorted(t, a, "right")
        if self.tau > 0:
            b_left, b_right = np.searchsorted(t, b, "left"), np.searchsorted(t, b, "right")
        else:
            b_left, b_right = a_left, a_right
        return Window(x, a, b, a_left, a_right, b_left, b_right)

    def _combine(self, lo: np.ndarray, hi: np.ndarray, ya: np.ndarray, yb: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        upper = np.maximum(self._hi.query(lo, hi), np.maximum(self._g(ya, True), self._g(yb, True)))
        lower = np.minimum(-self._lo_neg.query(lo, hi), np.minimum(self._g(ya, False), self._g(yb, False)))
        return lower, upper

    def bounds(self, w: Window, side: Literal["left", "right", "closed"]) -> tuple[np.ndarray, np.ndarray]:
        """``(lower, upper)`` at ``w.x``: left limits, right limits or ``"closed"`` (the instant)."""
        t, y = self.t, self.y
        if side == "left":  # window [x - tau, x + tau), approached from the left
            return self._combine(
                w.a_left, w.b_left, interp_at(t, y, w.a, w.a_left, "left"), interp_at(t, y, w.b, w.b_left, "left")
            )
        if side == "right":  # window (x - tau, x + tau], approached from the right
            return self._combine(
                w.a_right,
                w.b_right,
                interp_at(t, y, w.a, w.a_right, "right"),
                interp_at(t, y, w.b, w.b_right, "right"),
            )
        # closed window [x - tau, x + tau]: the value at the instant itself
        return self._combine(
            w.a_left, w.b_right, interp_at(t, y, w.a, w.a_right, "right"), interp_at(t, y, w.b, w.b_left, "left")
        )

    def breakpoints(self, w: Window) -> np.ndarray:
        """Times between consecutive points of the grid ``w.x`` where a bound changes its piece.

        ``w.x`` must contain every reference time ``+-tau`` that lies in its span.
        Then inside an interval ``(p, q)`` of it a bound is the max (min) of three
        linear pieces: the window's vertices (a constant, since none enters or
        leaves), the value at the window's left end and at its right end. The
        returned times are the pairwise crossings of these pieces inside ``(p, q)``.
        """
        if self.tau <= 0 or w.x.size < 2:
            return np.empty(0)
        t, y = self.t, self.y
        p, q = w.x[:-1], w.x[1:]
        # Vertices inside the window for every instant of (p, q):
        lo, hi = w.a_right[:-1], w.b_left[1:]
        left_end = (
            interp_at(t, y, w.a[:-1], w.a_right[:-1], "right"),
            interp_at(t, y, w.a[1:], w.a_left[1:], "left"),
        )
        right_end = (
            interp_at(t, y, w.b[:-1], w.b_right[:-1], "right"),
            interp_at(t, y, w.b[1:], w.b_left[1:], "left"),
        )
        found = []
        for upper in (True, False):
            sign = 1.0 if upper else -1.0
            const = (self._hi if upper else self._lo_neg).query(lo, hi)
            pieces = [(const, const)]
            pieces += [(sign * self._g(yp, upper), sign * self._g(yq, upper)) for yp, yq in (left_end, right_end)]
            for i, j in ((0, 1), (0, 2), (1, 2)):
                dp = pieces[i][0] - pieces[j][0]
                dq = pieces[i][1] - pieces[j][1]
                with np.errstate(invalid="ignore", over="ignore"):
                    hit = np.isfinite(dp) & np.isfinite(dq) & (dp * dq < 0)
                if hit.any():
                    ph, qh = p[hit], q[hit]
                    cross = ph + dp[hit] / (dp[hit] - dq[hit]) * (qh - ph)
                    found.append(cross[(cross > ph) & (cross < qh)])
        if not found:
            return np.empty(0)
        return np.unique(np.concatenate(found))

    def refine(self, w: Window) -> Window:
        """*w* with :meth:`breakpoints` added to its grid."""
        extra = self.breakpoints(w)
        if not extra.size:
            return w
        more = self.window(extra)
        order = np.argsort(np.concatenate([w.x, extra]), kind="stable")
        return Window(*(np.concatenate([getattr(w, f), getattr(more, f)])[order] for f in WINDOW_FIELDS))


def positive_fraction(u: np.ndarray, w: np.ndarray) -> np.ndarray:
    """Fraction of [0, 1] on which the linear function from *u* to *w* is positive."""
    with np.errstate(divide="ignore", invalid="ignore"):
        cross_down = np.where(u > 0, u / (u - w), 0.0)
        cross_up = np.where(w > 0, w / (w - u), 0.0)
    return np.where(
        (u > 0) & (w > 0), 1.0, np.where((u > 0) & (w <= 0), cross_down, np.where((w > 0) & (u <= 0), cross_up, 0.0))
    )


def group_middle(t: np.ndarray) -> np.ndarray:
    """Indices of samples that are neither the first nor the last at their time."""
    if t.size < 3:
        return np.empty(0, dtype=np.intp)
    same_prev = np.r_[False, t[1:] == t[:-1]]
    same_next = np.r_[t[1:] == t[:-1], False]
    return np.flatnonzero(same_prev & same_next)
