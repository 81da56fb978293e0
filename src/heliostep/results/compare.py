"""Compare simulation traces against reference traces with a tolerance tube.

The method follows the regression tools of the Modelica community (the Modelica
Association's ``funnel``, ITI's ``csv-compare``): a *tube* is built around the
reference and the actual trace passes when it stays inside the tube. See
``docs/compare.md`` for the full description; in short, for one signal with
tolerance ``Tolerance(abs=a, rel=r, time=tau)`` and the reference ``y(t)`` (the
polyline through its samples, with a jump wherever two samples share a time):

* value half-width ``h(y) = max(a, r*|y|)`` (the eFMI / ``max(absTol,
  relTol*|nominal|)`` convention, *not* ``a + r*|y|``);
* upper bound ``U(t) = max{ y(s) + h(y(s)) : s in [t - tau, t + tau] }``;
* lower bound ``L(t) = min{ y(s) - h(y(s)) : s in [t - tau, t + tau] }``;

the maximum and minimum are taken over the continuous polyline (every vertex in the
window, both sides of every jump, and the interpolated values at the window ends),
restricted to the time span of the reference. At a jump of either trace the check
is done on the left limit and on the right limit separately (and on any rows
between them); interpolation never crosses a jump.

The check is exact for the polylines, not just at sample points: it is evaluated on
a merged grid of the actual's times, the reference's times (which checks the
reference's points against the interpolated actual), the reference's times
shifted by ``+-tau`` (where a vertex enters or leaves the window) and the instants
where the tube's bounding piece changes. Between two grid points both the actual
and the bounds are linear, so no violation between grid points can be missed: a
spike of the actual between reference samples is caught, and so is a reference
feature between actual samples unless it is narrower than the time tolerance
(which the tube, by definition, tolerates).

Cost per signal is ``O(n log n)``: a sparse table answers window maxima in
constant time, window ends are located with :func:`numpy.searchsorted`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from types import MappingProxyType

import numpy as np
import pandas as pd

from heliostep.errors import InputError
from heliostep.results.trace_io import TIME, check_time
from heliostep.scenario import read_yaml_file

__all__ = [
    "Tolerance",
    "ToleranceSet",
    "SignalResult",
    "ComparisonResult",
    "SignalEvaluation",
    "compare_traces",
    "evaluate_signal",
    "load_tolerances",
]

_TOL_KEYS = ("abs", "rel", "time")


def _non_negative(value: object, what: str) -> float:
    if isinstance(value, bool):
        raise InputError(f"{what}: expected a non-negative number, got {value!r}")
    try:
        number = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        raise InputError(f"{what}: expected a non-negative number, got {value!r}") from None
    if not math.isfinite(number) or number < 0:
        raise InputError(f"{what}: expected a non-negative number, got {value!r}")
    return number


@dataclass(frozen=True)
class Tolerance:
    """Tolerance of one signal: absolute (signal units), relative (-), time (s)."""

    abs: float = 1e-6
    rel: float = 1e-4
    time: float = 1e-3

    def __post_init__(self) -> None:
        for name in _TOL_KEYS:
            object.__setattr__(self, name, _non_negative(getattr(self, name), f"tolerance {name!r}"))

    def half_width(self, values: np.ndarray) -> np.ndarray:
        """Half-width of the value band around reference *values*: ``max(abs, rel*|y|)``."""
        return np.maximum(self.abs, self.rel * np.abs(values))


@dataclass(frozen=True)
class ToleranceSet:
    """A default :class:`Tolerance` and per-signal overrides of some of its fields.

    ``signals`` maps a signal name to a mapping with some of the keys ``abs``,
    ``rel``, ``time``; the fields it does not give come from ``default``.
    """

    default: Tolerance = field(default_factory=Tolerance)
    signals: Mapping[str, Mapping[str, float]] = field(default_factory=dict)
    #: per scenario name, signal overrides that apply to that scenario only (:meth:`for_scenario`)
    scenarios: Mapping[str, Mapping[str, Mapping[str, float]]] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if not isinstance(self.default, Tolerance):
            raise InputError(f"default tolerance must be a Tolerance, not {type(self.default).__name__}")
        frozen = {}
        for name, override in self.signals.items():
            if isinstance(override, Tolerance):
                override = {k: getattr(override, k) for k in _TOL_KEYS}
            if not isinstance(override, Mapping):
                raise InputError(f"tolerance of signal {name!r} must be a mapping")
            checked = {}
            for key, value in override.items():
                if key not in _TOL_KEYS:
                    raise InputError(
                        f"tolerance of signal {name!r}: unknown key {key!r} (expected {', '.join(_TOL_KEYS)})"
                    )
                checked[key] = _non_negative(value, f"tolerance {key!r} of signal {name!r}")
            frozen[str(name)] = MappingProxyType(checked)
        object.__setattr__(self, "signals", MappingProxyType(frozen))

    def for_signal(self, name: str) -> Tolerance:
        """The tolerance that applies to signal *name*."""
        return replace(self.default, **self.signals.get(name, {}))

    def for_scenario(self, name: str) -> ToleranceSet:
        """The tolerances that apply to scenario *name*: its own section's signals over these."""
        own = self.scenarios.get(name, {})
        merged = {signal: {**self.signals.get(signal, {}), **own.get(signal, {})}
                  for signal in {*self.signals, *own}}
        return ToleranceSet(self.default, merged)

    def with_default(self, **changes: float) -> ToleranceSet:
        """A copy whose default has the given fields (``abs``, ``rel``, ``time``) replaced."""
        return ToleranceSet(replace(self.default, **changes), self.signals)


def load_tolerances(path: str | Path) -> ToleranceSet:
    """Read a YAML tolerance file.

    Format (both sections optional; numbers may be written ``1e-6``)::

        default: {abs: 1e-6, rel: 1e-4, time: 1e-3}
        signals:
          motor.tau: {abs: 1e-3}
        scenarios:            # optional: overrides for one scenario (by its name)
          jan21-weak-motor:
            signals:
              motor.tau: {abs: 1e-1}

    Fields missing from ``default`` keep the built-in defaults of :class:`Tolerance`.
    Unknown keys, non-numbers and negative numbers raise
    :class:`~heliostep.errors.InputError` naming the file and the key.
    """
    path = Path(path)
    data = read_yaml_file(path, "tolerance")  # heliostep's one YAML reader: a repeated key is an error
    if data is None:
        data = {}
    if not isinstance(data, Mapping):
        raise InputError(f"{path}: expected a mapping with keys 'default' and 'signals'")

    def section(value: object, where: str) -> dict[str, float]:
        if value is None:
            return {}
        if not isinstance(value, Mapping):
            raise InputError(f"{path}: {where}: expected a mapping of {', '.join(_TOL_KEYS)}")
        out = {}
        for key, number in value.items():
            if key not in _TOL_KEYS:
                raise InputError(f"{path}: unknown key {key!r} in {where} (expected {', '.join(_TOL_KEYS)})")
            try:
                out[key] = _non_negative(number, f"{where}.{key}")
            except InputError as exc:
                raise InputError(f"{path}: {exc}") from None
        return out

    def signal_sections(value: object, where: str) -> dict[str, dict[str, float]]:
        if value is None:
            return {}
        if not isinstance(value, Mapping):
            raise InputError(f"{path}: '{where}' must map signal names to tolerances")
        return {str(name): section(entry, f"{where}.{name}") for name, entry in value.items()}

    for key in data:
        if key not in ("default", "signals", "scenarios"):
            raise InputError(f"{path}: unknown key {key!r} (expected 'default', 'signals', 'scenarios')")
    default = Tolerance(**section(data.get("default"), "default"))
    signals = signal_sections(data.get("signals"), "signals")
    raw_scenarios = data.get("scenarios") or {}
    if not isinstance(raw_scenarios, Mapping):
        raise InputError(f"{path}: 'scenarios' must map scenario names to {{signals: ...}}")
    scenarios = {}
    for name, entry in raw_scenarios.items():
        if not isinstance(entry, Mapping) or set(entry) - {"signals"}:
            raise InputError(f"{path}: scenarios.{name}: expected a mapping with the key 'signals'")
        scenarios[str(name)] = signal_sections(entry.get("signals"), f"scenarios.{name}.signals")
    return ToleranceSet(default, signals, scenarios)


def _as_tolerance_set(tolerances: Tolerance | ToleranceSet | Mapping[str, Tolerance] | None) -> ToleranceSet:
    if tolerances is None:
        return ToleranceSet()
    if isinstance(tolerances, ToleranceSet):
        return tolerances
    if isinstance(tolerances, Tolerance):
        return ToleranceSet(tolerances)
    if isinstance(tolerances, Mapping):
        return ToleranceSet(Tolerance(), dict(tolerances))
    raise InputError(f"tolerances: expected a Tolerance or ToleranceSet, not {type(tolerances).__name__}")


# --------------------------------------------------------------------------- numerics


def _interp_at(t: np.ndarray, y: np.ndarray, x: np.ndarray, idx: np.ndarray, side: str) -> np.ndarray:
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


def _interp(t: np.ndarray, y: np.ndarray, x: np.ndarray, side: str) -> np.ndarray:
    """Like :func:`_interp_at`, locating *x* itself."""
    return _interp_at(t, y, x, np.searchsorted(t, x, side=side), side)


class _RangeMax:
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
class _Window:
    """Query times *x* with the window ends ``x -+ tau`` located in the reference times."""

    x: np.ndarray
    a: np.ndarray  # x - tau
    b: np.ndarray  # x + tau
    a_left: np.ndarray  # searchsorted(t, a, "left"), ...
    a_right: np.ndarray
    b_left: np.ndarray
    b_right: np.ndarray


_WINDOW_FIELDS = ("x", "a", "b", "a_left", "a_right", "b_left", "b_right")


class _Tube:
    """The tolerance tube around one reference signal (see module docstring)."""

    def __init__(self, t: np.ndarray, y: np.ndarray, tol: Tolerance) -> None:
        self.tol = tol
        self.tau = tol.time
        self.t, self.y = self._insert_kinks(t, y, tol)
        h = tol.half_width(self.y)
        self._hi = _RangeMax(self.y + h)
        self._lo_neg = _RangeMax(h - self.y)  # max of -(y - h)

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

    def window(self, x: np.ndarray) -> _Window:
        t = self.t
        a, b = x - self.tau, x + self.tau
        a_left, a_right = np.searchsorted(t, a, "left"), np.searchsorted(t, a, "right")
        if self.tau > 0:
            b_left, b_right = np.searchsorted(t, b, "left"), np.searchsorted(t, b, "right")
        else:
            b_left, b_right = a_left, a_right
        return _Window(x, a, b, a_left, a_right, b_left, b_right)

    def _combine(self, lo, hi, ya, yb) -> tuple[np.ndarray, np.ndarray]:
        upper = np.maximum(self._hi.query(lo, hi), np.maximum(self._g(ya, True), self._g(yb, True)))
        lower = np.minimum(-self._lo_neg.query(lo, hi), np.minimum(self._g(ya, False), self._g(yb, False)))
        return lower, upper

    def bounds(self, w: _Window, side: str) -> tuple[np.ndarray, np.ndarray]:
        """``(lower, upper)`` at ``w.x``: left limits, right limits or ``"closed"`` (the instant)."""
        t, y = self.t, self.y
        if side == "left":  # window [x - tau, x + tau), approached from the left
            return self._combine(
                w.a_left, w.b_left, _interp_at(t, y, w.a, w.a_left, "left"), _interp_at(t, y, w.b, w.b_left, "left")
            )
        if side == "right":  # window (x - tau, x + tau], approached from the right
            return self._combine(
                w.a_right,
                w.b_right,
                _interp_at(t, y, w.a, w.a_right, "right"),
                _interp_at(t, y, w.b, w.b_right, "right"),
            )
        # closed window [x - tau, x + tau]: the value at the instant itself
        return self._combine(
            w.a_left, w.b_right, _interp_at(t, y, w.a, w.a_right, "right"), _interp_at(t, y, w.b, w.b_left, "left")
        )

    def breakpoints(self, w: _Window) -> np.ndarray:
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
            _interp_at(t, y, w.a[:-1], w.a_right[:-1], "right"),
            _interp_at(t, y, w.a[1:], w.a_left[1:], "left"),
        )
        right_end = (
            _interp_at(t, y, w.b[:-1], w.b_right[:-1], "right"),
            _interp_at(t, y, w.b[1:], w.b_left[1:], "left"),
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

    def refine(self, w: _Window) -> _Window:
        """*w* with :meth:`breakpoints` added to its grid."""
        extra = self.breakpoints(w)
        if not extra.size:
            return w
        more = self.window(extra)
        order = np.argsort(np.concatenate([w.x, extra]), kind="stable")
        return _Window(*(np.concatenate([getattr(w, f), getattr(more, f)])[order] for f in _WINDOW_FIELDS))


def _positive_fraction(u: np.ndarray, w: np.ndarray) -> np.ndarray:
    """Fraction of [0, 1] on which the linear function from *u* to *w* is positive."""
    with np.errstate(divide="ignore", invalid="ignore"):
        cross_down = np.where(u > 0, u / (u - w), 0.0)
        cross_up = np.where(w > 0, w / (w - u), 0.0)
    return np.where(
        (u > 0) & (w > 0), 1.0, np.where((u > 0) & (w <= 0), cross_down, np.where((w > 0) & (u <= 0), cross_up, 0.0))
    )


@dataclass(frozen=True)
class SignalResult:
    """Verdict and figures of one signal.

    ``max_excess`` is the largest distance of the actual outside the tube (0 when
    inside), ``time_max_excess`` where the actual comes closest to (or goes furthest
    beyond) the tube's edge; ``max_abs_diff`` is the largest ``|actual - reference|``
    (both interpolated, no tolerance) and ``time_max_abs_diff`` where it is.
    ``outside_fraction`` is the time the actual spends outside the tube divided by
    the reference's duration (a part of the reference the actual does not reach,
    beyond the time tolerance, counts as outside). ``note`` explains special cases.
    """

    name: str
    passed: bool
    tolerance: Tolerance
    max_excess: float
    time_max_excess: float
    max_abs_diff: float
    time_max_abs_diff: float
    outside_fraction: float
    outside_duration: float
    note: str = ""


@dataclass(frozen=True)
class SignalEvaluation:
    """Arrays of one signal's check, for plotting.

    ``time`` holds every grid time twice (left limit, then right limit), so the
    arrays draw jumps as vertical segments. ``excess`` is how far the actual lies
    outside the tube (positive: outside, in signal units).
    """

    time: np.ndarray
    actual: np.ndarray
    reference: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    excess: np.ndarray
    result: SignalResult


@dataclass(frozen=True)
class ComparisonResult:
    """Result of :func:`compare_traces`: one :class:`SignalResult` per compared signal."""

    signals: Mapping[str, SignalResult]
    actual_name: str = "actual"
    reference_name: str = "reference"
    only_in_actual: tuple[str, ...] = ()
    only_in_reference: tuple[str, ...] = ()

    @property
    def passed(self) -> bool:
        """True when every compared signal passed."""
        return all(r.passed for r in self.signals.values())

    @property
    def failed(self) -> list[str]:
        """Names of the signals that failed, in comparison order."""
        return [name for name, r in self.signals.items() if not r.passed]

    def to_pandas(self) -> pd.DataFrame:
        """Summary table, one row per signal (index ``signal``)."""
        columns = [
            "passed",
            "max_excess",
            "time_max_excess",
            "max_abs_diff",
            "time_max_abs_diff",
            "outside_fraction",
        ]
        rows = []
        for r in self.signals.values():
            row = {"signal": r.name, **{c: getattr(r, c) for c in columns}}
            row.update(abs_tol=r.tolerance.abs, rel_tol=r.tolerance.rel, time_tol=r.tolerance.time, note=r.note)
            rows.append(row)
        frame = pd.DataFrame(rows, columns=["signal", *columns, "abs_tol", "rel_tol", "time_tol", "note"])
        return frame.set_index("signal")


def _group_middle(t: np.ndarray) -> np.ndarray:
    """Indices of samples that are neither the first nor the last at their time."""
    if t.size < 3:
        return np.empty(0, dtype=np.intp)
    same_prev = np.r_[False, t[1:] == t[:-1]]
    same_next = np.r_[t[1:] == t[:-1], False]
    return np.flatnonzero(same_prev & same_next)


def evaluate_signal(
    actual_time: np.ndarray,
    actual_values: np.ndarray,
    reference_time: np.ndarray,
    reference_values: np.ndarray,
    tolerance: Tolerance,
    name: str = "signal",
) -> SignalEvaluation:
    """Check one signal; inputs must be finite, times non-decreasing, at least one sample.

    Returns the summary (``.result``) and the arrays on the check grid.
    """
    ta = np.asarray(actual_time, dtype=np.float64)
    ya = np.asarray(actual_values, dtype=np.float64)
    tr = np.asarray(reference_time, dtype=np.float64)
    yr = np.asarray(reference_values, dtype=np.float64)
    tau = tolerance.time
    duration = float(tr[-1] - tr[0])
    d0, d1 = max(ta[0], tr[0]), min(ta[-1], tr[-1])
    empty = np.empty(0)
    if d0 > d1:
        note = f"no common time: actual covers [{ta[0]:g}, {ta[-1]:g}] s, reference [{tr[0]:g}, {tr[-1]:g}] s"
        result = SignalResult(name, False, tolerance, math.inf, math.nan, math.inf, math.nan, 1.0, duration, note)
        return SignalEvaluation(empty, empty, empty, empty, empty, empty, result)

    tube = _Tube(tr, yr, tolerance)
    candidates = [ta, tube.t, np.array([d0, d1])]
    if tau > 0:
        candidates += [tube.t - tau, tube.t + tau]
    grid = np.concatenate(candidates)
    grid = np.unique(grid[(grid >= d0) & (grid <= d1)])
    window = tube.refine(tube.window(grid))
    grid = window.x

    aL, aR = _interp(ta, ya, grid, "left"), _interp(ta, ya, grid, "right")
    if tube.tau > 0:
        rL, rR = _interp(tr, yr, grid, "left"), _interp(tr, yr, grid, "right")
    else:  # the window ends are the grid points themselves: reuse their indices
        rL = _interp_at(tube.t, tube.y, grid, window.a_left, "left")
        rR = _interp_at(tube.t, tube.y, grid, window.a_right, "right")
    loL, upL = tube.bounds(window, "left")
    loR, upR = tube.bounds(window, "right")
    exL = np.maximum(aL - upL, loL - aL)
    exR = np.maximum(aR - upR, loR - aR)

    # Worst point beyond the tube: left and right limits, plus rows between them.
    ex_all = np.stack([exL, exR], axis=1).ravel()
    t_all = np.repeat(grid, 2)
    middle = _group_middle(ta)
    middle = middle[(ta[middle] >= d0) & (ta[middle] <= d1)]
    if middle.size:
        lo_m, up_m = tube.bounds(tube.window(ta[middle]), "closed")
        ex_m = np.maximum(ya[middle] - up_m, lo_m - ya[middle])
        ex_check = np.concatenate([ex_all, ex_m])
        t_check = np.concatenate([t_all, ta[middle]])
    else:
        ex_check, t_check = ex_all, t_all
    k = int(np.argmax(ex_check))
    worst_excess, time_excess = float(ex_check[k]), float(t_check[k])

    diff = np.abs(np.stack([aL - rL, aR - rR], axis=1).ravel())
    kd = int(np.argmax(diff))

    # Time outside the tube: between grid points both bounds and the actual are linear.
    dt = np.diff(grid)
    outside = float(
        np.sum(
            dt
            * (
                _positive_fraction((aR - upR)[:-1], (aL - upL)[1:])
                + _positive_fraction((loR - aR)[:-1], (loL - aL)[1:])
            )
        )
    )
    notes = []
    passed = worst_excess <= 0
    uncovered = max(ta[0] - tr[0], 0.0) + max(tr[-1] - ta[-1], 0.0)
    if ta[0] > tr[0] + tau or ta[-1] < tr[-1] - tau:
        passed = False
        outside += uncovered
        notes.append(
            f"actual covers [{ta[0]:g}, {ta[-1]:g}] s, reference [{tr[0]:g}, {tr[-1]:g}] s"
        )
    if duration > 0:
        fraction = min(outside / duration, 1.0)
    else:
        fraction = 0.0 if passed else 1.0
    result = SignalResult(
        name=name,
        passed=bool(passed),
        tolerance=tolerance,
        max_excess=max(worst_excess, 0.0),
        time_max_excess=time_excess,
        max_abs_diff=float(diff[kd]),
        time_max_abs_diff=float(t_all[kd]),
        outside_fraction=float(fraction),
        outside_duration=min(outside, duration) if duration > 0 else outside,
        note="; ".join(notes),
    )
    return SignalEvaluation(
        time=t_all,
        actual=np.stack([aL, aR], axis=1).ravel(),
        reference=np.stack([rL, rR], axis=1).ravel(),
        lower=np.stack([loL, loR], axis=1).ravel(),
        upper=np.stack([upL, upR], axis=1).ravel(),
        excess=ex_all,
        result=result,
    )


# --------------------------------------------------------------------------- tables


def _column(df: pd.DataFrame, column: str, name: str) -> np.ndarray:
    series = df[column]
    if isinstance(series, pd.DataFrame):
        raise InputError(f"{name}: duplicate column {column!r}")
    if len(series) and not (pd.api.types.is_numeric_dtype(series) or pd.api.types.is_bool_dtype(series)):
        raise InputError(f"{name}: column {column!r} is not numeric (dtype {series.dtype})")
    try:
        return series.to_numpy(dtype=np.float64, na_value=np.nan)
    except (TypeError, ValueError) as exc:
        raise InputError(f"{name}: column {column!r} is not numeric: {exc}") from None


def _check_table(df: pd.DataFrame, name: str) -> np.ndarray:
    if not isinstance(df, pd.DataFrame):
        raise InputError(f"{name}: expected a pandas DataFrame, not {type(df).__name__}")
    if TIME not in df.columns:
        raise InputError(f"{name}: no {TIME!r} column")
    time = _column(df, TIME, name)
    if time.size == 0:
        raise InputError(f"{name}: no rows")
    check_time(time, name)
    return time


def _check_finite(values: np.ndarray, time: np.ndarray, column: str, name: str) -> None:
    bad = np.flatnonzero(~np.isfinite(values))
    if bad.size:
        i = int(bad[0])
        kind = "NaN" if np.isnan(values[i]) else "a non-finite value"
        raise InputError(
            f"{name}: column {column!r} has {kind} in data row {i + 1} (time {float(time[i])!r} s)"
            + (f" and {bad.size - 1} more row(s)" if bad.size > 1 else "")
        )


def _signal_names(df: pd.DataFrame) -> list[str]:
    return [str(c) for c in df.columns if str(c) != TIME]


def compare_traces(
    actual: pd.DataFrame,
    reference: pd.DataFrame,
    tolerances: Tolerance | ToleranceSet | Mapping[str, Tolerance] | None = None,
    signals: Sequence[str] | None = None,
    *,
    actual_name: str = "actual",
    reference_name: str = "reference",
) -> ComparisonResult:
    """Compare the signals of *actual* with those of *reference*.

    *actual* and *reference* are trace tables (a ``time`` column and signal
    columns). *tolerances* is a :class:`Tolerance` for every signal, a
    :class:`ToleranceSet`, a mapping signal name -> :class:`Tolerance` (others get
    the default), or None (``Tolerance()`` defaults). *signals* selects the signals
    to compare (default: every signal present in both, in the reference's order).
    *actual_name* / *reference_name* (e.g. file names) appear in error messages.

    Raises :class:`~heliostep.errors.InputError` for bad input: a missing ``time``
    column or signal, time that is not finite and non-decreasing, NaN or infinite
    values in a compared signal, no signal to compare.
    """
    tol_set = _as_tolerance_set(tolerances)
    ta = _check_table(actual, actual_name)
    tr = _check_table(reference, reference_name)
    in_actual, in_reference = _signal_names(actual), _signal_names(reference)
    if signals is None:
        selected = [s for s in in_reference if s in set(in_actual)]
        if not selected:
            raise InputError(f"no signal in common between {actual_name} and {reference_name}")
    else:
        if isinstance(signals, str):
            signals = [signals]
        selected = list(dict.fromkeys(str(s) for s in signals))
        if not selected:
            raise InputError("no signal selected")
        for s in selected:
            if s == TIME:
                raise InputError(f"{TIME!r} is the time column, not a signal")
            missing = [n for n, present in ((actual_name, in_actual), (reference_name, in_reference)) if s not in present]
            if missing:
                raise InputError(f"{' and '.join(missing)}: no column {s!r} (requested signal)")
    results: dict[str, SignalResult] = {}
    for s in selected:
        ya = _column(actual, s, actual_name)
        yr = _column(reference, s, reference_name)
        _check_finite(ya, ta, s, actual_name)
        _check_finite(yr, tr, s, reference_name)
        results[s] = evaluate_signal(ta, ya, tr, yr, tol_set.for_signal(s), name=s).result
    actual_set, reference_set = set(in_actual), set(in_reference)
    return ComparisonResult(
        signals=MappingProxyType(results),
        actual_name=actual_name,
        reference_name=reference_name,
        only_in_actual=tuple(s for s in in_actual if s not in reference_set),
        only_in_reference=tuple(s for s in in_reference if s not in actual_set),
    )


def _num(x: float, spec: str) -> str:
    return "-" if not math.isfinite(x) else format(x, spec)


def format_table(result: ComparisonResult) -> str:
    """The per-signal summary printed by the command."""
    head = ("signal", "verdict", "outside tube", "at t [s]", "max |diff|", "at t [s]", "time outside")
    rows = [
        (
            r.name,
            "ok" if r.passed else "FAIL",
            _num(r.max_excess, ".3g"),
            _num(r.time_max_excess if r.max_excess > 0 else math.nan, ".6g"),
            _num(r.max_abs_diff, ".3g"),
            _num(r.time_max_abs_diff if r.max_abs_diff > 0 else math.nan, ".6g"),
            f"{100 * r.outside_fraction:.3g}%",
        )
        for r in result.signals.values()
    ]
    widths = [max(len(row[i]) for row in (head, *rows)) for i in range(len(head))]

    def line(cells: tuple[str, ...]) -> str:
        first = cells[0].ljust(widths[0])
        rest = [cells[1].ljust(widths[1])] + [c.rjust(w) for c, w in zip(cells[2:], widths[2:])]
        return "  ".join([first, *rest]).rstrip()

    out = [line(head)] + [line(row) for row in rows]
    for r in result.signals.values():
        if r.note:
            out.append(f"note: {r.name}: {r.note}")
    return "\n".join(out)
