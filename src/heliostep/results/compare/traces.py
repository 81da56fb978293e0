"""Compare simulation traces against reference traces with a tolerance tube.

A trace passes when it stays inside a tube of half-width max(abs, rel |y|) around the reference,
widened by a time tolerance, checked exactly on the polylines (docs/compare.md); every public name
of :mod:`~heliostep.results.compare.tolerance` and :mod:`~heliostep.results.compare.tube` is importable from here.

Details: docs/compare.md, ``heliostep.results.compare.traces``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from types import MappingProxyType

import numpy as np
import pandas as pd

from heliostep.errors import InputError
from heliostep.results.compare.signal_map import SignalMatch
from heliostep.results.compare.tolerance import Tolerance, ToleranceSet, as_tolerance_set, load_tolerances
from heliostep.results.compare.tube import Tube, Window, group_middle, interp, interp_at, positive_fraction
from heliostep.results.trace.files import TIME, check_time

__all__ = [
    "Tolerance",
    "ToleranceSet",
    "SignalResult",
    "ComparisonResult",
    "SignalEvaluation",
    "compare_matched",
    "compare_traces",
    "evaluate_signal",
    "load_tolerances",
]


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
    #: at ``time_max_excess``: actual minus reference [signal units] and the tube's half-width
    #: ``(U - L) / 2`` there [signal units] (what a CI failure message quotes)
    deviation_at_max_excess: float = math.nan
    half_width_at_max_excess: float = math.nan


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
    #: per compared (reference) signal, the actual column it was compared with and how it was
    #: matched (:func:`compare_matched`); a signal absent here was matched by its name
    matches: Mapping[str, SignalMatch] = field(default_factory=dict)

    def match_of(self, name: str) -> SignalMatch:
        """How reference signal *name* found its actual column."""
        return self.matches.get(name) or SignalMatch(name, name, "name")

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
    d0, d1 = max(ta[0], tr[0]), min(ta[-1], tr[-1])
    if d0 > d1:
        return _no_common_time(ta, tr, tolerance, name)

    tube = Tube(tr, yr, tolerance)
    window = _check_window(ta, tube, d0, d1)
    grid = window.x
    aL, aR = interp(ta, ya, grid, "left"), interp(ta, ya, grid, "right")
    if tube.tau > 0:
        rL, rR = interp(tr, yr, grid, "left"), interp(tr, yr, grid, "right")
    else:  # the window ends are the grid points themselves: reuse their indices
        rL = interp_at(tube.t, tube.y, grid, window.a_left, "left")
        rR = interp_at(tube.t, tube.y, grid, window.a_right, "right")
    loL, upL = tube.bounds(window, "left")
    loR, upR = tube.bounds(window, "right")
    exL = np.maximum(aL - upL, loL - aL)
    exR = np.maximum(aR - upR, loR - aR)
    ex_all = np.stack([exL, exR], axis=1).ravel()
    t_all = np.repeat(grid, 2)
    a_all, r_all = np.stack([aL, aR], axis=1).ravel(), np.stack([rL, rR], axis=1).ravel()
    lo_all, up_all = np.stack([loL, loR], axis=1).ravel(), np.stack([upL, upR], axis=1).ravel()
    worst_excess, time_excess, at_worst = _worst_excess(ta, ya, tube, ex_all, t_all, d0, d1)
    if at_worst is None:  # a grid point: its values are on the grid
        k = int(np.argmax(ex_all))
        at_worst = (float(a_all[k] - r_all[k]), float(0.5 * (up_all[k] - lo_all[k])))

    diff = np.abs(a_all - r_all)
    kd = int(np.argmax(diff))
    outside = _time_outside(grid, aL, aR, loL, upL, loR, upR)
    result = _signal_result(
        name, tolerance, ta, tr, worst_excess, time_excess, float(diff[kd]), float(t_all[kd]), outside
    )
    result = replace(result, deviation_at_max_excess=at_worst[0], half_width_at_max_excess=at_worst[1])
    return SignalEvaluation(
        time=t_all, actual=a_all, reference=r_all, lower=lo_all, upper=up_all, excess=ex_all, result=result
    )


def _no_common_time(ta: np.ndarray, tr: np.ndarray, tolerance: Tolerance, name: str) -> SignalEvaluation:
    """The failed check of a signal whose actual and reference share no time."""
    duration = float(tr[-1] - tr[0])
    empty = np.empty(0)
    note = f"no common time: actual covers [{ta[0]:g}, {ta[-1]:g}] s, reference [{tr[0]:g}, {tr[-1]:g}] s"
    result = SignalResult(name, False, tolerance, math.inf, math.nan, math.inf, math.nan, 1.0, duration, note)
    return SignalEvaluation(empty, empty, empty, empty, empty, empty, result)


def _check_window(ta: np.ndarray, tube: Tube, d0: float, d1: float) -> Window:
    """The check grid on the common span ``[d0, d1]`` [s] with its windows: the actual's times, the
    reference's (and, with a time tolerance, shifted by ``+-tau``), the span's ends, and the
    instants where a bound of the tube changes its piece."""
    tau = tube.tol.time
    candidates = [ta, tube.t, np.array([d0, d1])]
    if tau > 0:
        candidates += [tube.t - tau, tube.t + tau]
    grid = np.concatenate(candidates)
    grid = np.unique(grid[(grid >= d0) & (grid <= d1)])
    return tube.refine(tube.window(grid))


def _worst_excess(
    ta: np.ndarray, ya: np.ndarray, tube: Tube, ex_all: np.ndarray, t_all: np.ndarray, d0: float, d1: float
) -> tuple[float, float, tuple[float, float] | None]:
    """The largest excess beyond the tube and its time [s]: over the left and right limits on the grid
    (*ex_all* at *t_all*), plus the actual's rows between the two limits of a jump in ``[d0, d1]``.
    When the worst is such a row, also its deviation from the reference and the tube's half-width
    there (else None: the grid has them)."""
    middle = group_middle(ta)
    middle = middle[(ta[middle] >= d0) & (ta[middle] <= d1)]
    if not middle.size:
        k = int(np.argmax(ex_all))
        return float(ex_all[k]), float(t_all[k]), None
    lo_m, up_m = tube.bounds(tube.window(ta[middle]), "closed")
    ex_m = np.maximum(ya[middle] - up_m, lo_m - ya[middle])
    k_grid, k_mid = int(np.argmax(ex_all)), int(np.argmax(ex_m))
    if ex_all[k_grid] >= ex_m[k_mid]:
        return float(ex_all[k_grid]), float(t_all[k_grid]), None
    t_m = ta[middle[k_mid : k_mid + 1]]
    reference = float(interp(tube.t, tube.y, t_m, "left")[0])
    at_worst = (float(ya[middle[k_mid]] - reference), float(0.5 * (up_m[k_mid] - lo_m[k_mid])))
    return float(ex_m[k_mid]), float(t_m[0]), at_worst


def _time_outside(
    grid: np.ndarray,
    aL: np.ndarray,
    aR: np.ndarray,
    loL: np.ndarray,
    upL: np.ndarray,
    loR: np.ndarray,
    upR: np.ndarray,
) -> float:
    """Time [s] the actual spends outside the tube on *grid*, from the left (``L``) and right (``R``)
    limits of the actual and the bounds: between grid points both bounds and the actual are linear."""
    dt = np.diff(grid)
    return float(
        np.sum(
            dt
            * (positive_fraction((aR - upR)[:-1], (aL - upL)[1:]) + positive_fraction((loR - aR)[:-1], (loL - aL)[1:]))
        )
    )


def _signal_result(
    name: str,
    tolerance: Tolerance,
    ta: np.ndarray,
    tr: np.ndarray,
    worst_excess: float,
    time_excess: float,
    max_abs_diff: float,
    time_max_abs_diff: float,
    outside: float,
) -> SignalResult:
    """The verdict of one signal; an actual that stops short of the reference's span by more than the
    time tolerance fails, the part it misses counting as outside [s]."""
    tau = tolerance.time
    duration = float(tr[-1] - tr[0])
    notes = []
    passed = worst_excess <= 0
    uncovered = max(ta[0] - tr[0], 0.0) + max(tr[-1] - ta[-1], 0.0)
    if ta[0] > tr[0] + tau or ta[-1] < tr[-1] - tau:
        passed = False
        outside += uncovered
        notes.append(f"actual covers [{ta[0]:g}, {ta[-1]:g}] s, reference [{tr[0]:g}, {tr[-1]:g}] s")
    if duration > 0:
        fraction = min(outside / duration, 1.0)
    else:
        fraction = 0.0 if passed else 1.0
    return SignalResult(
        name=name,
        passed=bool(passed),
        tolerance=tolerance,
        max_excess=max(worst_excess, 0.0),
        time_max_excess=time_excess,
        max_abs_diff=max_abs_diff,
        time_max_abs_diff=time_max_abs_diff,
        outside_fraction=float(fraction),
        outside_duration=min(outside, duration) if duration > 0 else outside,
        note="; ".join(notes),
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
    tol_set = as_tolerance_set(tolerances)
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
            sources = ((actual_name, in_actual), (reference_name, in_reference))
            missing = [n for n, present in sources if s not in present]
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


def compare_matched(
    actual: pd.DataFrame,
    reference: pd.DataFrame,
    matches: Mapping[str, SignalMatch],
    tolerances: Tolerance | ToleranceSet | Mapping[str, Tolerance] | None = None,
    *,
    actual_name: str = "actual",
    reference_name: str = "reference",
    every_match: Mapping[str, SignalMatch] | None = None,
) -> ComparisonResult:
    """Compare each reference signal of *matches* (from
    :func:`~heliostep.results.compare.signal_map.match_signals`) with its actual column; results and
    tolerances are by the reference's names. ``only_in_actual`` / ``only_in_reference`` list the
    columns that *every_match* (default: *matches*; all the matches when *matches* is a selection)
    leaves unmatched."""
    if not matches:
        raise InputError(f"no signal of {reference_name} is matched in {actual_name}")
    _check_table(actual, actual_name)
    renamed = pd.DataFrame({TIME: actual[TIME], **{ref: actual[m.actual] for ref, m in matches.items()}})
    result = compare_traces(
        renamed, reference, tolerances, list(matches), actual_name=actual_name, reference_name=reference_name
    )
    every_match = matches if every_match is None else every_match
    used = {m.actual for m in every_match.values()}
    return replace(
        result,
        matches=MappingProxyType(dict(matches)),
        only_in_actual=tuple(s for s in _signal_names(actual) if s not in used),
        only_in_reference=tuple(s for s in _signal_names(reference) if s not in every_match),
    )


def format_matches(result: ComparisonResult) -> str:
    """One line per compared signal saying which actual column it was compared with and how."""
    matches = [result.match_of(name) for name in result.signals]
    if all(m.how == "name" for m in matches):
        return f"matched by name: all {len(matches)} signal(s)"
    return "\n".join(f"matched: {m.describe()}" for m in matches)


def _num(x: float, spec: str) -> str:
    return "-" if not math.isfinite(x) else format(x, spec)


def format_table(result: ComparisonResult, units: Mapping[str, str] | None = None) -> str:
    """The per-signal summary printed by the command; *units* (signal -> unit) fill its last column."""
    units = units or {}
    head = ("signal", "verdict", "outside tube", "at t [s]", "max |diff|", "at t [s]", "time outside", "unit")
    rows = [
        (
            r.name,
            "ok" if r.passed else "FAIL",
            _num(r.max_excess, ".3g"),
            _num(r.time_max_excess if r.max_excess > 0 else math.nan, ".6g"),
            _num(r.max_abs_diff, ".3g"),
            _num(r.time_max_abs_diff if r.max_abs_diff > 0 else math.nan, ".6g"),
            f"{100 * r.outside_fraction:.3g}%",
            units.get(r.name, "-"),
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
