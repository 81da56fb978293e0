"""The figures of a run accumulated in the compiled kernel, at every solution row.

:class:`FigureSpec` says what to accumulate (plain arrays: the columns of a row, the panel
reference as a piecewise cubic, the steps and their commands, the envelope's bins, the window
around the peak); :class:`KernelFigures` holds kernel.h's ``hs_figures`` for one run. The kernel
updates it at each row it records (every internal CVODE step and every output time), the master
passes it the rows it records itself (both sides of every event): so the internal steps' rows are
no longer handed to Python. :meth:`KernelFigures.totals` reads the result back
(:class:`FigureTotals`) for :class:`heliostep.results.figures.solution.SolutionRecorder`, whose own
Python code on blocks of rows is the definition it follows (the same operations on each value; the
sums over rows taken one row after the other, so they differ from numpy's pairwise sums in
rounding only).
"""

from __future__ import annotations

import ctypes
import dataclasses
import os
from typing import Any

import numpy as np

from heliostep.cosim import kernel as kernel_module

__all__ = ["KERNEL_FIGURES", "FigureSpec", "FigureTotals", "KernelFigures"]

#: Accumulate the figures in the kernel when the monitor allows it (``HELIOSTEP_KERNEL_FIGURES=0``:
#: every solution row handed to the monitor in Python, as before).
KERNEL_FIGURES = os.environ.get("HELIOSTEP_KERNEL_FIGURES", "1") != "0"


@dataclasses.dataclass(frozen=True)
class FigureSpec:
    """What the kernel accumulates (columns of the master's rows; -1: none).

    ``breaks`` [s] and ``coefs`` (4 x len(breaks) - 1, scipy ``PPoly.c``) are the panel reference
    [rad]; ``step_times`` [s] and ``commanded`` [rad] the steps, ``initial_command`` [rad] the
    command before the first, ``increment`` and ``period`` [rad], ``band`` [increments] and
    ``miss_tolerance`` [increments] how they are judged; ``enveloped`` the columns binned in
    ``bins`` bins over ``span`` [s]; ``plotted`` the columns kept within ``half_width`` [s] of the
    peak |torque| (time first, the torque second), at most ``max_rows`` rows.
    """

    torque: int
    currents: tuple[int, ...]
    power: int
    panel: int
    rotor: int
    breaks: np.ndarray
    coefs: np.ndarray
    step_times: np.ndarray
    commanded: np.ndarray
    initial_command: float
    increment: float
    period: float
    band: float
    miss_tolerance: float
    enveloped: tuple[int, ...]
    span: tuple[float, float]
    bins: int
    plotted: tuple[int, ...]
    half_width: float
    max_rows: int


@dataclasses.dataclass(frozen=True)
class FigureTotals:
    """What the kernel accumulated: rows taken, the first (time [s], rotor [rad]) and the last row,
    peaks, the energy [J], the error [deg] (max, integral of e^2, sum of e^2), the outcomes of the
    steps judged (rows of missed, settling [s] or NaN, move [increments]), the envelope
    (least, largest, worst magnitude, its (time, value)), the rows around the peak
    (its time [s] and signed torque), the error's integral [deg s] and its values at the steps' times, the
    rows of its extremes per interval between them (t, e, panel of the largest, then of the least [s, deg, rad];
    the intervals reached), and the integral of e^2 [deg^2 s] (one row after the other) to the end and at the
    steps' times (:meth:`heliostep.results.figures.solution.SolutionRecorder.figures`' ``error_*``)."""

    count: int
    unordered: int
    first: tuple[float, float]
    last: np.ndarray
    last_time_repeated: bool
    peak_torque: float
    peak_current: float
    energy: float
    error_max: float
    error_sq_int: float
    error_sq_sum: float
    last_error: float
    outcomes: np.ndarray
    max_held: int
    lag: float
    low: np.ndarray
    high: np.ndarray
    worst: np.ndarray
    worst_at: np.ndarray
    window: np.ndarray
    peak: float
    peak_time: float
    peak_value: float
    error_int: float
    error_marks: np.ndarray
    extremes: np.ndarray
    error_sq_marks: np.ndarray


_LONGS = ("torque", "power", "panel", "rotor", "n_currents")


_FIELDS: list[tuple[str, Any]] = (
    [(name, ctypes.c_long) for name in _LONGS]
    + [("currents", ctypes.c_void_p), ("n_breaks", ctypes.c_long), ("breaks", ctypes.c_void_p)]
    + [("coefs", ctypes.c_void_p), ("n_steps", ctypes.c_long)]
    + [(name, ctypes.c_void_p) for name in ("step_times", "commanded")]
    + [(name, ctypes.c_double) for name in ("initial_command", "increment", "period", "band", "miss_tolerance")]
    + [("outcomes", ctypes.c_void_p), ("n_enveloped", ctypes.c_long), ("bins", ctypes.c_long)]
    + [("enveloped", ctypes.c_void_p), ("env_start", ctypes.c_double), ("env_end", ctypes.c_double)]
    + [(name, ctypes.c_void_p) for name in ("low", "high", "worst", "worst_at")]
    + [("n_plotted", ctypes.c_long), ("max_rows", ctypes.c_long), ("plotted", ctypes.c_void_p)]
    + [("half_width", ctypes.c_double), ("window", ctypes.c_void_p), ("trail", ctypes.c_void_p)]
    + [
        (name, ctypes.c_long)
        for name in (
            "count",
            "unordered",
            "window_rows",
            "trail_rows",
            "judged",
            "open",
            "held",
            "held_capacity",
            "max_held",
            "last_repeated",
            "interval",
        )
    ]
    + [
        (name, ctypes.c_double)
        for name in (
            "first_time",
            "first_rotor",
            "lag",
            "previous",
            "until",
            "peak",
            "peak_time",
            "peak_value",
            "peak_torque",
            "peak_current",
            "energy",
            "error_max",
            "error_sq_int",
            "error_sq_sum",
            "last_error",
        )
    ]
    + [(name, ctypes.c_void_p) for name in ("last", "held_t", "held_x")]
    + [("error_int", ctypes.c_double), ("error_marks", ctypes.c_void_p), ("marked", ctypes.c_long)]
    + [("extremes", ctypes.c_void_p), ("error_sq_marks", ctypes.c_void_p)]
)


class FigureState(ctypes.Structure):
    """kernel.h ``hs_figures``."""

    _fields_ = _FIELDS


class KernelFigures:
    """kernel.h ``hs_figures`` for one run of rows ``width`` values wide, set up from ``spec``;
    :attr:`address` goes into the kernel's ``figures``. :meth:`row` takes a row the master
    records itself; :meth:`totals` judges the open step and reads the result (once)."""

    def __init__(self, spec: FigureSpec, width: int):
        self.spec, self.width = spec, width
        lib = kernel_module.library()
        lib.hs_figures_row.argtypes = [ctypes.c_void_p, ctypes.c_void_p, ctypes.c_long]
        lib.hs_figures_row.restype = ctypes.c_int
        lib.hs_figures_finish.argtypes = [ctypes.c_void_p, ctypes.c_double]
        lib.hs_figures_free.argtypes = [ctypes.c_void_p]
        lib.hs_figures_judge_open.argtypes = [ctypes.c_void_p, ctypes.c_double]
        self._library = lib
        s = self.state = FigureState()
        s.torque, s.power, s.panel, s.rotor = spec.torque, spec.power, spec.panel, spec.rotor
        n_env, n_plot = len(spec.enveloped), len(spec.plotted)
        self._arrays = arrays = {
            "currents": np.array(spec.currents, dtype=np.int64),
            "breaks": np.ascontiguousarray(spec.breaks, dtype=float),
            "coefs": np.ascontiguousarray(spec.coefs, dtype=float),
            "step_times": np.ascontiguousarray(spec.step_times, dtype=float),
            "commanded": np.ascontiguousarray(spec.commanded, dtype=float),
            "outcomes": np.full((len(spec.step_times), 3), np.nan),
            "enveloped": np.array(spec.enveloped, dtype=np.int64),
            "low": np.full((n_env, spec.bins), np.nan),
            "high": np.full((n_env, spec.bins), np.nan),
            "worst": np.full(n_env, -np.inf),
            "worst_at": np.full((n_env, 2), np.nan),
            "plotted": np.array(spec.plotted, dtype=np.int64),
            "window": np.zeros((spec.max_rows, n_plot)),
            "trail": np.zeros((spec.max_rows, n_plot)),
            "last": np.full(width, np.nan),
            "error_marks": np.full(max(len(spec.step_times), 1), np.nan),
            "extremes": np.full((len(spec.step_times) + 1, 6), np.nan),
            "error_sq_marks": np.full(max(len(spec.step_times), 1), np.nan),
        }
        for name, array in arrays.items():
            setattr(s, name, array.ctypes.data)
        s.n_currents, s.n_breaks, s.n_steps = len(spec.currents), len(spec.breaks), len(spec.step_times)
        s.initial_command, s.increment, s.period = spec.initial_command, spec.increment, spec.period
        s.band, s.miss_tolerance = spec.band, spec.miss_tolerance
        s.n_enveloped, s.bins, (s.env_start, s.env_end) = n_env, spec.bins, spec.span
        s.n_plotted, s.max_rows, s.half_width = n_plot, spec.max_rows, spec.half_width
        s.peak, s.interval = -np.inf, -1
        s.first_time = s.first_rotor = s.lag = s.peak_time = s.peak_value = np.nan
        self.address = ctypes.cast(ctypes.pointer(s), ctypes.c_void_p).value
        self._totals: FigureTotals | None = None

    def row(self, row: np.ndarray) -> None:
        """One solution row the master recorded itself (an event's, the first, the last)."""
        row = np.ascontiguousarray(row, dtype=float).reshape(-1)
        if self._library.hs_figures_row(self.address, row.ctypes.data, self.width):
            raise MemoryError("no memory for the rotor's rows of one step interval")

    def totals(self) -> FigureTotals:
        """The figures accumulated, the step open at the last row judged up to it (once; then kept)."""
        if self._totals is None:
            if self.state.count:
                self._library.hs_figures_finish(self.address, self._arrays["last"][0])
            self._totals = self._read(self.state)
        return self._totals

    def snapshot(self) -> FigureTotals:
        """The figures so far, the open step judged up to the last row on a copy (the run goes on)."""
        if self._totals is not None:
            return self._totals
        copy = FigureState.from_buffer_copy(self.state)
        if copy.count:
            self._library.hs_figures_judge_open(ctypes.addressof(copy), self._arrays["last"][0])
        return self._read(copy)

    def _read(self, s: FigureState) -> FigureTotals:
        a = self._arrays
        return FigureTotals(
            int(s.count),
            int(s.unordered),
            (float(s.first_time), float(s.first_rotor)),
            a["last"].copy(),
            bool(s.last_repeated),
            float(s.peak_torque),
            float(s.peak_current),
            float(s.energy),
            float(s.error_max),
            float(s.error_sq_int),
            float(s.error_sq_sum),
            float(s.last_error),
            a["outcomes"][: int(s.judged)].copy(),
            int(s.max_held),
            float(s.lag),
            a["low"].copy(),
            a["high"].copy(),
            a["worst"].copy(),
            a["worst_at"].copy(),
            a["window"][: int(s.window_rows)].copy(),
            float(s.peak),
            float(s.peak_time),
            float(s.peak_value),
            float(s.error_int),
            a["error_marks"][: int(s.marked)].copy(),
            a["extremes"][: int(s.marked) + 1].copy(),
            a["error_sq_marks"][: int(s.marked)].copy(),
        )

    def close(self) -> None:
        """The open step's rows freed (also done by :meth:`totals`)."""
        self._library.hs_figures_free(self.address)

    def __del__(self) -> None:
        self.close()
