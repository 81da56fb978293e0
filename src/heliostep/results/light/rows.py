"""The light's integrals between the output rows: the solution's correction of the rows' trapezoid.

Where the output rows miss the panel's swing after a step, each power that depends on the driven
angle is corrected to second order in the tracking error by the solution's integrals of the error
and its square.

Details: docs/light.md, ``heliostep.results.light.rows``.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence

import numpy as np
import pandas as pd

__all__ = ["RowMarks", "corrections", "swing_rows"]


class RowMarks:
    """The rows' side of the correction, accumulated block by block, at the first row and at the first row at
    or after each step's time (``step_times`` [s]; the marks), and at the last row: the trapezoids of the
    driven angle's error e [rad s] and of e^2 [rad^2 s] over the rows, the sum over the rows' intervals of h^2
    times the reference's change [rad s^2], e at the marks, and there the slopes [W/rad] of each power
    (``slopes(rows)``: name -> slope at the rows of the block given by their indices; a name ending in
    ``"''"``: the second derivative [W/rad^2] of the power named before it)."""

    def __init__(self, step_times: Sequence[float]):
        self.step_times = np.asarray(step_times, dtype=float)
        self.integral = self.square = self.curvature = 0.0  # to the last row
        self.marks: list[float] = []  # the integral of e at the first row, then at each step's time
        self.square_marks: list[float] = []
        self.curvature_marks: list[float] = []
        self.mark_times: list[float] = []
        self.mark_errors: list[float] = []
        self.slopes: dict[str, list[float]] = {}
        self.end_time: float | None = None
        self._previous: tuple[float, float, float] | None = None  # the last row's (time, error, reference)

    def __call__(
        self,
        seconds: np.ndarray,
        error: np.ndarray,
        reference: np.ndarray,
        slopes: Callable[[np.ndarray], Mapping[str, np.ndarray]],
    ) -> None:
        if not len(seconds):
            return
        time, e, ref = seconds, error, reference
        if self._previous is not None:
            before_t, before_e, before_ref = self._previous
            time, e, ref = (
                np.concatenate([[v], a]) for v, a in ((before_t, seconds), (before_e, error), (before_ref, reference))
            )
        h = np.diff(time)
        sums = [
            np.cumsum(np.concatenate([[start], terms]))
            for start, terms in (
                (self.integral, h * (e[:-1] + e[1:]) / 2.0),
                (self.square, h * (e[:-1] ** 2 + e[1:] ** 2) / 2.0),  # what the rows' trapezoid of a power takes
                (self.curvature, h * h * np.diff(ref)),
            )
        ]
        if self._previous is not None:
            sums = [values[1:] for values in sums]
        marked = np.empty(0, dtype=int)
        if not self.marks:  # the first row opens the first interval
            marked = np.array([0])
        steps = self.step_times[len(self.marks) - 1 :] if self.marks else self.step_times  # those not yet marked
        steps = steps[steps <= seconds[-1]]
        if len(steps):
            marked = np.concatenate([marked, np.searchsorted(seconds, steps, side="left")])
        if len(marked):
            for kept, values in zip((self.marks, self.square_marks, self.curvature_marks), sums, strict=True):
                kept.extend(values[marked].tolist())
            self.mark_times.extend(seconds[marked].tolist())
            self.mark_errors.extend(error[marked].tolist())
            for name, slope in slopes(marked).items():
                self.slopes.setdefault(name, []).extend(np.asarray(slope, dtype=float).tolist())
        self.integral, self.square, self.curvature = (float(values[-1]) for values in sums)
        self.end_time = float(seconds[-1])
        self._previous = (float(seconds[-1]), float(error[-1]), float(reference[-1]))


def _rates(slope: np.ndarray, times: np.ndarray) -> np.ndarray:
    """The slope's rate of change in time over each interval [W/(rad s)], from the marks' slopes: to the next
    mark's, the last interval's as the one before it (0 with one mark)."""
    rates = np.zeros(len(slope))
    if len(slope) > 1:
        span = np.diff(times[: len(slope)])
        rates[:-1] = np.divide(np.diff(slope), span, out=np.zeros(len(span)), where=span > 0)
        rates[-1] = rates[-2]
    return rates


def corrections(rows: RowMarks, solution: Mapping | None) -> dict[str, float]:
    """Each power's correction [J] (the module's docstring) from the rows' marks and, for the part between the
    rows, the solution's figures (``error_integral_*``, ``error_sq_integral_*``, ``end_time_s``; without them, a
    stored run from before them, the curvature term alone)."""
    if not rows.marks:
        return {}
    count = len(rows.marks)
    exact = exact_sq = None
    if solution is not None and "error_integral_at_steps_deg_s" in solution:
        exact = np.radians(np.concatenate([[0.0], np.asarray(solution["error_integral_at_steps_deg_s"], dtype=float)]))
        count = min(len(exact), count)  # the first row and the steps both have reached
        exact = exact[:count]
        if "error_sq_integral_at_steps_deg2_s" in solution:
            marks = np.asarray(solution["error_sq_integral_at_steps_deg2_s"], dtype=float)
            exact_sq = (np.radians(1.0) ** 2 * np.concatenate([[0.0], marks]))[:count]
    approximate, square = np.asarray(rows.marks[:count]), np.asarray(rows.square_marks[:count])
    bent, times = np.asarray(rows.curvature_marks[:count]), np.asarray(rows.mark_times[:count])
    end = rows.end_time if exact is None else solution.get("end_time_s")  # type: ignore[union-attr]
    if end is not None and rows.end_time is not None and abs(end - rows.end_time) <= 1e-9 * max(1.0, abs(end)):
        approximate, square = np.append(approximate, rows.integral), np.append(square, rows.square)
        bent, times = np.append(bent, rows.curvature), np.append(times, rows.end_time)
        if exact is not None:
            exact = np.append(exact, np.radians(solution["error_integral_deg_s"]))  # type: ignore[index]
        if exact_sq is not None:
            exact_sq = np.append(exact_sq, np.radians(1.0) ** 2 * solution["error_sq_integral_deg2_s"])  # type: ignore[index]
    intervals = len(approximate) - 1
    missed = np.zeros(intervals) if exact is None else np.diff(exact) - np.diff(approximate)  # D1 [rad s]
    missed_sq = np.zeros(intervals) if exact_sq is None else np.diff(exact_sq) - np.diff(square)  # D2 [rad^2 s]
    curvature = np.diff(bent)  # sum of h^2 d(theta_ref) per interval [rad s^2]
    error = np.asarray(rows.mark_errors[:intervals])
    out = {}
    for name, values in rows.slopes.items():
        if name.endswith("''"):
            continue
        slope = np.asarray(values[:intervals])
        second = rows.slopes.get(name + "''")
        if second is not None:  # a power of the actual attitude: about the reference, S = dP - C e, and C D2 / 2
            curved = np.asarray(second[:intervals])
            slope = slope - curved * error
            extra = float(np.dot(curved, missed_sq)) / 2.0
        else:
            extra = 0.0
        # the rows' line through a held angle: the trapezoid of (slope x error), both linear in a row's
        # interval, errs by -h d(slope) d(error) / 6, d(error) = -d(theta_ref) while the panel is held
        out[name] = float(np.dot(slope, missed) + np.dot(_rates(slope, times), curvature[:intervals]) / 6.0) + extra
    return out


def swing_rows(solution: Mapping | None, panel: str | None) -> pd.DataFrame | None:
    """Rows at the solution's extremes of the tracking error in each interval between steps
    (``error_extremes_deg``: the panel's swing, which the output rows may step over): ``time`` [s] and the
    ``panel`` column [rad] (``panel_angle_ref`` set to it: only the actual attitude is asked of them), in
    time order; None without them (a stored run from before them, no panel)."""
    extremes = None if solution is None else solution.get("error_extremes_deg")
    if not extremes or panel is None:
        return None
    rows = np.array([[np.nan if v is None else v for v in row] for row in extremes], dtype=float).reshape(-1, 3)
    rows = rows[np.isfinite(rows[:, [0, 2]]).all(axis=1)]
    if not len(rows):
        return None
    rows = rows[np.argsort(rows[:, 0], kind="stable")]
    return pd.DataFrame({"time": rows[:, 0], "panel_angle_ref": rows[:, 2], panel: rows[:, 2]})
