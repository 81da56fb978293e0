"""Where a PCHIP reference crosses a lattice of levels, and in which direction: the step scheduler's roots.

A piece that is strictly monotone and brackets a level has one crossing there, found for all such pieces at
once by safeguarded Newton steps to the resolution of time; the few others (a level at a knot, a flat or
barely monotone piece) by scipy's root finder, as ``PPoly.solve`` finds them.

Details: docs/physics.md, ``heliostep.drive.sequencer``.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from scipy.interpolate import PchipInterpolator

try:  # the root finder of scipy's PPoly.solve, called as it calls it (without its per-call Python)
    from scipy.interpolate._ppoly import real_roots as _real_roots
except ImportError:  # pragma: no cover - another scipy: the same through the public API
    from scipy.interpolate import PPoly

    def _real_roots(c, x, y, discontinuity, extrapolate):
        return [PPoly.construct_fast(c[:, :, 0], x, extrapolate=extrapolate).solve(y, discontinuity, extrapolate)]


__all__ = ["STOP_CHECK_STEPS", "LevelCrossings", "PreparationStopped", "bracketed_roots"]

#: Levels solved by scipy's root finder, and steps scheduled, between two looks at the stop request.
STOP_CHECK_STEPS = 1024

#: More Newton or bisection steps than a bracket of any width needs to shrink to a float's spacing.
MAX_ITERATIONS = 200


class PreparationStopped(Exception):
    """A stop request (SIGINT, SIGTERM, SIGHUP) came while the inputs were prepared: nothing was computed."""


class LevelCrossings:
    """Where a PCHIP reference crosses levels, in which direction; each level solved once, on the pieces that
    bracket it (PCHIP is monotone on every interval): by :func:`bracketed_roots` where the piece is strictly
    monotone and the level lies strictly between its ends, by scipy's root finder (that of ``PPoly.solve``)
    elsewhere.

    A piece is not solved at a level that steps cross in one direction only when it is monotone the other way
    with a margin over the rounding of its slope (none of its crossings could be a step's), unless a piece solved
    at that level is near enough for their roots to merge.
    """

    def __init__(self, reference: PchipInterpolator) -> None:
        self.reference = reference
        self.start, self.stop = reference.x[0], reference.x[-1]
        self.slope = reference.derivative()
        self.knots = reference.x
        self._piece_c = np.ascontiguousarray(np.transpose(reference.c)[:, :, None, None])  # piece k: (4, 1, 1)
        self._piece_x = np.ascontiguousarray(np.stack([self.knots[:-1], self.knots[1:]], axis=1))  # piece k: (2,)
        ends = reference(self.knots)
        self.piece_low, self.piece_high = np.minimum(ends[:-1], ends[1:]), np.maximum(ends[:-1], ends[1:])
        self.margin = 1e-12 * max(1.0, float(np.abs(ends).max()))
        self.widths = np.diff(self.knots)
        self.rising, self.falling = _monotone_slopes(self.slope.c, self.widths)

    def lattice(self, sequencer, step: float) -> tuple[int, np.ndarray, np.ndarray]:
        """The up and down levels (position ± ``step``) of every step index of ``sequencer`` from the first to the
        last whose levels can lie within the reference's range, two more each side: (first index, ups, downs). An
        index beyond has no level in the range: no step leads to it or from it."""
        low, high = float(self.piece_low.min()) - self.margin, float(self.piece_high.max()) + self.margin
        increment, offset = sequencer.increment, sequencer.offset
        first = int(np.floor((low - offset - step) / increment)) - 2
        last = int(np.ceil((high - offset + step) / increment)) + 2
        positions = sequencer.position(np.arange(first, last + 1))
        return first, positions + step, positions - step

    def solve(
        self, levels: np.ndarray, wanted: np.ndarray, should_stop: Callable[[], bool] | None = None
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The crossings of the sorted ``levels`` in (start, stop]: times [s] and directions (+1 up, -1 down,
        0 a touch), by level then time, and where each level's begin (``bounds[j]:bounds[j + 1]``). ``wanted``:
        per level, whether steps cross it upwards, downwards; crossings no step can take may be left out.
        ``should_stop``: asked after every :data:`STOP_CHECK_STEPS` pieces solved; when True,
        :class:`PreparationStopped` is raised."""
        which, pieces = self._pairs(levels)
        solved = self._needed(which, pieces, wanted)
        which, pieces = which[solved], pieces[solved]
        values = levels[which]
        monotone = (self.rising | self.falling)[pieces]
        inside = (values > self.piece_low[pieces] + self.margin) & (values < self.piece_high[pieces] - self.margin)
        bracketed = monotone & inside
        k = pieces[bracketed]
        c = self.reference.c[:, k]
        single = bracketed_roots(c, self.knots[k], self.widths[k], values[bracketed], self.rising[k])
        if len(k) >= STOP_CHECK_STEPS and should_stop is not None and should_stop():
            raise PreparationStopped(f"stopped while solving the step levels ({len(k)} of {len(pieces)} so far)")
        others = ~bracketed
        found = self._roots(pieces[others].tolist(), values[others].tolist(), should_stop)
        counts = np.fromiter(map(len, found), dtype=np.intp, count=len(found))
        roots = np.concatenate([single, *found])
        level = np.concatenate([which[bracketed], np.repeat(which[others], counts)])
        finite = np.isfinite(roots)
        roots, level = roots[finite], level[finite]
        order = np.lexsort((roots, level))
        roots, level = roots[order], level[order]
        # near-duplicates merged (a root at a knot found on both pieces), then kept in (start, stop]
        repeated = np.zeros(len(roots), dtype=bool)
        repeated[1:] = (level[1:] == level[:-1]) & ~(
            roots[1:] - roots[:-1] > 1e-12 * np.maximum(1.0, np.abs(roots[1:]))
        )
        kept = ~repeated & (self.start < roots) & (roots <= self.stop)
        roots, level = roots[kept], level[kept]
        return roots, self._directions(roots, levels[level]), np.searchsorted(level, np.arange(len(levels) + 1))

    def _pairs(self, levels: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(level, piece) of every piece whose end values bracket a level (within the margin), by level then piece."""
        begin = np.searchsorted(levels, self.piece_low - self.margin, side="left")
        end = np.searchsorted(levels, self.piece_high + self.margin, side="right")
        counts = np.maximum(end - begin, 0)
        pieces = np.repeat(np.arange(len(begin)), counts)
        which = np.repeat(begin - np.cumsum(counts) + counts, counts) + np.arange(int(counts.sum()))
        order = np.argsort(which, kind="stable")
        return which[order], pieces[order]

    def _needed(self, which: np.ndarray, pieces: np.ndarray, wanted: np.ndarray) -> np.ndarray:
        """Per (level, piece) pair, whether it is solved: not when the level is wanted down (up) only and the piece
        rises (falls), so that none of its crossings can be wanted, unless a pair of the level that is solved lies
        so near that their roots could be merged (twice the merging distance)."""
        idle = (~wanted[which, 0] & self.rising[pieces]) | (~wanted[which, 1] & self.falling[pieces])
        count, at = len(which), np.arange(len(which))
        before = np.maximum.accumulate(np.where(idle, -1, at))  # the nearest pair solved anyway, at or before
        after = np.minimum.accumulate(np.where(idle, count, at)[::-1])[::-1]  # at or after
        gap = 2e-12 * max(1.0, float(np.abs(self.knots).max()))
        prior, next_ = np.maximum(before, 0), np.minimum(after, count - 1)
        knots = self.knots
        near = (before >= 0) & (which[prior] == which) & (knots[pieces] - knots[pieces[prior] + 1] <= gap)
        near |= (after < count) & (which[next_] == which) & (knots[pieces[next_]] - knots[pieces + 1] <= gap)
        return ~idle | near

    def _roots(self, pieces: list[int], values: list[float], should_stop: Callable[[], bool] | None) -> list:
        """The roots of each piece at its level: scipy's ``PPoly.solve(level, extrapolate=False)`` on the piece
        alone, called as it calls its root finder (on the piece's coefficients, C-contiguous)."""
        piece_c, piece_x, found = list(self._piece_c), list(self._piece_x), []  # (views: faster to pick from a list)
        for begin in range(0, len(pieces), STOP_CHECK_STEPS):
            if begin and should_stop is not None and should_stop():
                raise PreparationStopped(f"stopped while solving the step levels ({begin} of {len(pieces)} so far)")
            found += [
                _real_roots(piece_c[k], piece_x[k], y, True, False)[0]
                for k, y in zip(pieces[begin : begin + STOP_CHECK_STEPS], values[begin : begin + STOP_CHECK_STEPS])
            ]
        return found

    def _directions(self, roots: np.ndarray, levels: np.ndarray) -> np.ndarray:
        """+1 where the reference crosses upwards at ``roots``, -1 downwards, 0 where it only touches: the
        slope's sign, or where it is zero (or not finite) the values either side."""
        slopes = self.slope(roots)
        directions = np.where(slopes > 0, 1, np.where(slopes < 0, -1, 0))
        for j in np.nonzero(~np.isfinite(slopes) | (slopes == 0))[0].tolist():
            directions[j] = _crossing_direction(self.reference, float(slopes[j]), float(roots[j]), float(levels[j]))
        return directions


def bracketed_roots(
    c: np.ndarray, start: np.ndarray, width: np.ndarray, level: np.ndarray, rising: np.ndarray
) -> np.ndarray:
    """The crossing [s] of each cubic piece at its level, where the piece is strictly monotone over
    (``start``, ``start + width``) and the level strictly between its end values (so it crosses once).

    Safeguarded Newton steps (Numerical Recipes' ``rtsafe``), all pieces at once: a Newton step where it lands
    inside the bracket the value's sign keeps and at most halves the step before, else bisection; a piece is
    done when its step is below the spacing of floats at its time, or its value is exactly the level.

    Parameters
    ----------
    c : array (4, n)
        Each piece's coefficients, highest power first, in the time from its start (``PPoly.c``).
    start, width : arrays (n,)  [s]
    level : array (n,)
        The level each piece crosses (the reference's unit).
    rising : array of bool (n,)
        Whether the piece rises (else it falls).

    Returns
    -------
    array (n,)  [s]
    """
    a, b, q, d = c[0], c[1], c[2], c[3] - level
    at_end = ((a * width + b) * width + q) * width + d
    s = np.clip(width * d / (d - at_end), 0.0, width)  # where the chord crosses the level
    low, high = np.zeros_like(width), np.array(width, dtype=float)
    sign = np.where(rising, 1.0, -1.0)
    last_step = np.array(width, dtype=float)
    active = np.arange(len(width))
    roots = np.full(len(width), np.nan)
    for _ in range(MAX_ITERATIONS):
        if not len(active):
            break
        f = ((a * s + b) * s + q) * s + d
        slope = (3.0 * a * s + 2.0 * b) * s + q
        below = sign * f < 0.0  # the root lies after s
        low, high = np.where(below, s, low), np.where(below, high, s)
        with np.errstate(divide="ignore", invalid="ignore"):
            newton = s - f / slope
        newtonian = (newton > low) & (newton < high) & (np.abs(2.0 * f) <= np.abs(last_step * slope))
        moved = np.where(newtonian, newton, 0.5 * (low + high))
        last_step = np.abs(moved - s)
        done = (f == 0.0) | (last_step <= np.spacing(start + s))
        roots[active[done]] = start[done] + np.where(f == 0.0, s, moved)[done]
        going = ~done
        active, s = active[going], moved[going]
        a, b, q, d, start, sign = a[going], b[going], q[going], d[going], start[going], sign[going]
        low, high, last_step = low[going], high[going], last_step[going]
    roots[active] = start + s  # (none are left: a step is at most half the one before it, or halves the bracket)
    return roots


def _monotone_slopes(c: np.ndarray, widths: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per piece of a slope (quadratic pieces ``c``, highest power first, over ``widths``): whether its value as
    computed is > 0 (rising) or < 0 (falling) at every point of the piece and at the start of the next one (where
    a crossing at the knot takes its slope): the extreme over the piece beyond the rounding of the evaluation."""
    a, b, c0 = c
    at_end = (c0 + b * widths) + a * (widths * widths)
    with np.errstate(divide="ignore", invalid="ignore"):
        vertex = -b / (2 * a)
        top = c0 - b * b / (4 * a)  # the value at the vertex
    inside = (a != 0) & (vertex > 0) & (vertex < widths)
    least = np.where(inside & (a > 0), np.minimum(np.minimum(c0, at_end), top), np.minimum(c0, at_end))
    most = np.where(inside & (a < 0), np.maximum(np.maximum(c0, at_end), top), np.maximum(c0, at_end))
    rounding = 64 * np.finfo(float).eps * (np.abs(c0) + np.abs(b) * widths + np.abs(a) * widths * widths)
    finite = np.isfinite(rounding)
    next_start = np.concatenate([c0[1:], [np.nan]])
    last = np.arange(len(c0)) == len(c0) - 1  # the last piece's end is its own
    rising = finite & (least > rounding) & (last | (next_start > 0))
    falling = finite & (most < -rounding) & (last | (next_start < 0))
    return rising, falling


def _crossing_direction(reference, d: float, t: float, level: float) -> int:
    """+1 if the reference crosses ``level`` upwards at ``t`` (where its slope is ``d``), −1 downwards, 0 if
    it only touches."""
    if np.isfinite(d) and d != 0:
        return 1 if d > 0 else -1
    eps = 1e-6 * max(1.0, abs(t))
    before, after = reference(t - eps), reference(t + eps)
    if np.isnan(before) or np.isnan(after) or (before - level) * (after - level) >= 0:
        return 0
    return 1 if after > level else -1
