"""Open-loop stepping: the phase-current sequencer and the step scheduler.

Steps are commanded at the exact instants the reference crosses a half-step boundary (``midpoint``)
or reaches the next position (``reach``), roots of a PCHIP interpolant of the reference.

Details: docs/physics.md, ``heliostep.drive.sequencer``.
"""

from __future__ import annotations

import bisect
from collections.abc import Callable
from dataclasses import dataclass
from typing import Literal

import numpy as np
from scipy.interpolate import PchipInterpolator

try:  # the root finder of scipy's PPoly.solve, called as it calls it (without its per-call Python)
    from scipy.interpolate._ppoly import real_roots as _real_roots
except ImportError:  # pragma: no cover - another scipy: the same through the public API
    from scipy.interpolate import PPoly

    def _real_roots(c, x, y, discontinuity, extrapolate):
        return [PPoly.construct_fast(c[:, :, 0], x, extrapolate=extrapolate).solve(y, discontinuity, extrapolate)]


from heliostep.errors import InputError
from heliostep.scenario import SEQUENCER_MODES, SEQUENCER_TRIGGERS, SequencerConfig

#: Phase patterns (phase A, phase B) per step index, in the order that turns the rotor forward.
PATTERNS = {
    "one-phase-on": ((1, 0), (0, -1), (-1, 0), (0, 1)),  # [paper], Table 1
    "two-phase-on": ((1, -1), (-1, -1), (-1, 1), (1, 1)),
    "half-step": ((1, 0), (1, -1), (0, -1), (-1, -1), (-1, 0), (-1, 1), (0, 1), (1, 1)),
}


#: Microstep divisions of a full step a driver offers (1: full steps).
MICROSTEPS = (1, 2, 4, 8, 16)

#: Step triggers: the fraction of a step increment the reference must move past the
#: commanded position before the next step is commanded.
TRIGGERS = {"midpoint": 0.5, "reach": 1.0}

if set(PATTERNS) != set(SEQUENCER_MODES) or set(TRIGGERS) != set(SEQUENCER_TRIGGERS):  # pragma: no cover
    raise ImportError("heliostep.drive.sequencer: patterns or triggers differ from the scenario's vocabulary")

_DEFAULTS = SequencerConfig()


@dataclass(frozen=True)
class Sequencer:
    """Phase-current sequencer of a two-phase stepper.

    Parameters
    ----------
    mode : {'one-phase-on', 'two-phase-on', 'half-step'}
    current : float
        Rated phase current I [A]; reference currents are pattern × I.
    step_angle : float
        Full-step angle [rad] (1.8° = π/(2 N_c) for N_c = 50).
    """

    mode: str = _DEFAULTS.mode
    current: float = _DEFAULTS.current
    step_angle: float = float(np.radians(_DEFAULTS.step_angle))
    microsteps: int = _DEFAULTS.microsteps
    idle_current_fraction: float = _DEFAULTS.idle_current_fraction
    idle_delay: float = _DEFAULTS.idle_delay

    def __post_init__(self):
        if self.mode not in PATTERNS:
            raise InputError(f"sequencer mode {self.mode!r}: expected one of {', '.join(PATTERNS)}")
        if not self.current > 0:
            raise InputError(f"sequencer current {self.current!r}: expected > 0 [A]")
        if not self.step_angle > 0:
            raise InputError(f"sequencer step_angle {self.step_angle!r}: expected > 0")
        if self.microsteps not in MICROSTEPS:
            raise InputError(f"sequencer microsteps {self.microsteps!r}: expected one of {MICROSTEPS}")
        if self.microsteps > 1 and self.mode != "one-phase-on":
            raise InputError(
                f"sequencer microsteps {self.microsteps}: needs mode one-phase-on "
                f"(sine/cosine currents), got {self.mode!r}"
            )
        if not 0.0 < self.idle_current_fraction <= 1.0:
            raise InputError(f"sequencer idle_current_fraction {self.idle_current_fraction!r}: expected in (0, 1]")
        if not self.idle_delay >= 0.0:
            raise InputError(f"sequencer idle_delay {self.idle_delay!r}: expected >= 0 [s]")

    @property
    def increment(self) -> float:
        """Rotor angle between successive step indices [rad]."""
        if self.microsteps > 1:
            return self.step_angle / self.microsteps
        return self.step_angle / 2 if self.mode == "half-step" else self.step_angle

    @property
    def offset(self) -> float:
        """Rotor angle held by step index 0 [rad] (two-phase-on sits half a step on)."""
        return self.step_angle / 2 if self.mode == "two-phase-on" else 0.0

    def position(self, index):
        """Rotor angle held by step ``index`` [rad] (vectorised)."""
        return self.offset + np.asarray(index) * self.increment

    def nearest_index(self, rotor_angle: float) -> int:
        """Step index whose position is nearest to ``rotor_angle`` [rad]."""
        return int(np.floor((rotor_angle - self.offset) / self.increment + 0.5))

    def reference_currents(self, index) -> tuple[np.ndarray, np.ndarray]:
        """Reference currents (i_a, i_b) [A] of step ``index`` (vectorised)."""
        if self.microsteps > 1:
            # sine/cosine microstepping: the electrical angle advances pi/2 per full step, so the
            # torque law ([paper], eq. 9) holds theta = phi / N_c; at multiples of N the currents
            # are the one-phase-on pattern (Table 1)
            phase = np.asarray(index) * (np.pi / 2) / self.microsteps
            return np.cos(phase) * self.current, -np.sin(phase) * self.current
        table = np.array(PATTERNS[self.mode], dtype=float)
        pattern = table[np.mod(np.asarray(index), len(table))]
        return pattern[..., 0] * self.current, pattern[..., 1] * self.current


@dataclass(frozen=True)
class StepSchedule:
    """When the sequencer steps and to which index.

    ``times[k]`` is the instant of the k-th step [s]; from it on the index is ``indices[k]``;
    before the first step it is ``initial_index``.
    """

    times: np.ndarray
    indices: np.ndarray
    initial_index: int

    def __len__(self) -> int:
        return len(self.times)

    def index_at(self, time, side: Literal["left", "right"] = "right") -> np.ndarray:
        """Commanded index at ``time`` [s]; ``side='left'`` gives the value just before a step."""
        k = np.searchsorted(self.times, time, side=side)
        all_indices = np.concatenate([[self.initial_index], self.indices])
        return all_indices[k]


def reference_interpolant(times: np.ndarray, rotor_angle_ref: np.ndarray) -> PchipInterpolator:
    """Monotone piecewise-cubic interpolant of the reference rotor angle [rad] over time [s]."""
    times = np.asarray(times, dtype=float)
    if times.ndim != 1 or len(times) < 2 or np.any(np.diff(times) <= 0):
        raise InputError("reference times: expected at least two strictly increasing values")
    if not np.all(np.isfinite(rotor_angle_ref)):
        raise InputError("reference rotor angle: expected finite values (no NaN)")
    return PchipInterpolator(times, rotor_angle_ref, extrapolate=False)


class PreparationStopped(Exception):
    """A stop request (SIGINT, SIGTERM, SIGHUP) came while the inputs were prepared: nothing was computed."""


#: Steps scheduled between two looks at the stop request (few enough that a stop is seen at once).
STOP_CHECK_STEPS = 1024


def schedule_steps(
    reference: PchipInterpolator,
    sequencer: Sequencer,
    initial_index: int | None = None,
    trigger: str = "midpoint",
    should_stop: Callable[[], bool] | None = None,
) -> StepSchedule:
    """Step instants where the reference moves a trigger fraction past the commanded position.

    Parameters
    ----------
    reference : PchipInterpolator
        Reference rotor angle [rad] over time [s], from :func:`reference_interpolant`.
    sequencer : Sequencer
    initial_index : int, optional
        Index commanded at the start; default the one nearest the reference's first value.
    trigger : {'midpoint', 'reach'}
        Step when the reference crosses the midpoint to the next position, or reaches it.
    should_stop : callable, optional
        Asked every :data:`STOP_CHECK_STEPS` steps; when True, :class:`PreparationStopped` is raised.

    Returns
    -------
    StepSchedule
    """
    if trigger not in TRIGGERS:
        raise InputError(f"sequencer trigger {trigger!r}: expected one of {', '.join(TRIGGERS)}")
    fraction = TRIGGERS[trigger]
    start = reference.x[0]
    if initial_index is None:
        initial_index = sequencer.nearest_index(float(reference(start)))
    crossings = _LevelCrossings(reference)
    increment = sequencer.increment
    step = fraction * increment
    lattice = crossings.lattice(sequencer, step, initial_index, should_stop)  # every level with a crossing, at once
    next_crossing = crossings.next_crossing
    times, indices, index, t = [], [], initial_index, start
    while True:
        if lattice is not None and lattice[0] <= index < lattice[0] + len(lattice[1]):
            up_level, down_level = lattice[1][index - lattice[0]], lattice[2][index - lattice[0]]
        else:  # (never: the lattice spans the reference's range)
            position = float(sequencer.position(index))
            up_level, down_level = position + step, position - step
        up = next_crossing(up_level, +1, t)
        down = next_crossing(down_level, -1, t)
        if not np.isfinite(min(up, down)):
            break
        t, index = (up, index + 1) if up <= down else (down, index - 1)
        times.append(t)
        indices.append(index)
        if should_stop is not None and len(times) % STOP_CHECK_STEPS == 0 and should_stop():
            raise PreparationStopped(f"stopped while scheduling the steps ({len(times)} so far, t = {t:.6g} s)")
    return StepSchedule(np.array(times, dtype=float), np.array(indices, dtype=int), initial_index)


#: Levels solved at once at most (beyond, each level is solved when the walk reaches it).
LATTICE_MAX_LEVELS = 4_000_000


class _LevelCrossings:
    """Where a PCHIP reference crosses levels, in which direction; each level solved once.

    PCHIP is monotone on every interval, so only the pieces whose end values bracket a level
    can cross it: just those are solved (solving the whole spline per level is O(pieces)).
    """

    def __init__(self, reference: PchipInterpolator) -> None:
        self.reference = reference
        self.start, self.stop = reference.x[0], reference.x[-1]
        self.slope = reference.derivative()
        self._crossings: dict[float, tuple[list[float], list[int]]] = {}
        self.knots = reference.x
        self._piece_c = np.ascontiguousarray(np.transpose(reference.c)[:, :, None, None])  # piece k: (4, 1, 1)
        ends = reference(self.knots)
        self.piece_low, self.piece_high = np.minimum(ends[:-1], ends[1:]), np.maximum(ends[:-1], ends[1:])
        self.margin = 1e-12 * max(1.0, float(np.abs(ends).max()))

    def solve(self, level: float) -> list[float]:
        """The times where the reference equals ``level`` [rad], sorted, near-duplicates merged."""
        margin = self.margin
        pieces = np.nonzero((self.piece_low - margin <= level) & (level <= self.piece_high + margin))[0]
        return self._merged([t for k in pieces for t in self._piece_roots(int(k), level)])

    def _piece_roots(self, k: int, level: float) -> list[float]:
        """The finite roots of piece ``k`` at ``level``: scipy's ``PPoly.solve(level, extrapolate=False)`` on the
        piece alone, called as it calls its root finder (on the piece's coefficients, C-contiguous)."""
        roots = _real_roots(self._piece_c[k], self.knots[k : k + 2], level, True, False)[0]
        return [t for t in roots.tolist() if np.isfinite(t)]

    @staticmethod
    def _merged(roots: list[float]) -> list[float]:
        roots = sorted(roots)
        return [t for i, t in enumerate(roots) if i == 0 or t - roots[i - 1] > 1e-12 * max(1.0, abs(t))]

    def crossings_of(self, level: float) -> tuple[list[float], list[int]]:
        """Times in (start, stop] where the reference crosses ``level``, and the directions."""
        if level not in self._crossings:
            self._store([level], [self.solve(level)])
        return self._crossings[level]

    def _store(self, levels: list[float], solved: list[list[float]]) -> None:
        """The crossings of each of ``levels`` from its roots ``solved``; the slopes at all of them in one call."""
        kept = [[t for t in roots if self.start < t <= self.stop] for roots in solved]
        every = [t for roots in kept for t in roots]
        slopes = iter(self.slope(np.array(every, dtype=float)).tolist() if every else [])
        for level, roots in zip(levels, kept):  # (zip takes a slope only for a root)
            directions = [_crossing_direction(self.reference, d, t, level) for t, d in zip(roots, slopes)]
            self._crossings[level] = (roots, directions)

    def lattice(
        self, sequencer: Sequencer, step: float, initial_index: int, should_stop: Callable[[], bool] | None = None
    ) -> tuple[int, list, list] | None:
        """The up and down levels (position ± ``step``) of every step index whose levels lie within the
        reference's range, their crossings solved at once: (first index, up levels, down levels), or None
        when they would be more than :data:`LATTICE_MAX_LEVELS`. The same values as one level at a time:
        the same pieces per level, the same root finder on each, the same merging."""
        low, high = float(self.piece_low.min()) - self.margin, float(self.piece_high.max()) + self.margin
        increment, offset = sequencer.increment, sequencer.offset
        first = min(initial_index, int(np.floor((low - offset - step) / increment)) - 2)
        last = max(initial_index, int(np.ceil((high - offset + step) / increment)) + 2)
        if not 0 <= 2 * (last - first + 1) <= LATTICE_MAX_LEVELS:
            return None
        positions = sequencer.position(np.arange(first, last + 1))
        ups, downs = positions + step, positions - step
        levels = np.unique(np.concatenate([ups, downs]))
        # per piece, the levels it can cross (the test of solve, as two searches on the sorted levels)
        begin = np.searchsorted(levels, self.piece_low - self.margin, side="left")
        end = np.searchsorted(levels, self.piece_high + self.margin, side="right")
        counts = np.maximum(end - begin, 0)
        pieces = np.repeat(np.arange(len(begin)), counts)
        which = np.repeat(begin - np.cumsum(counts) + counts, counts) + np.arange(int(counts.sum()))
        order = np.argsort(which, kind="stable")  # by level, then piece (as solve's nonzero)
        found: dict[int, list[float]] = {}
        values = levels.tolist()
        for n, (j, k) in enumerate(zip(which[order].tolist(), pieces[order].tolist())):
            found.setdefault(j, []).extend(self._piece_roots(k, values[j]))
            if should_stop is not None and n % STOP_CHECK_STEPS == STOP_CHECK_STEPS - 1 and should_stop():
                raise PreparationStopped(f"stopped while solving the step levels ({n + 1} of {len(which)} so far)")
        solved = [j for j in found if values[j] not in self._crossings]
        self._store([values[j] for j in solved], [self._merged(found[j]) for j in solved])
        for level in values:
            self._crossings.setdefault(level, ([], []))
        return first, ups.tolist(), downs.tolist()

    def next_crossing(self, level: float, direction: int, after: float) -> float:
        """The first time [s] after ``after`` where the reference crosses ``level`` in ``direction``."""
        times, directions = self.crossings_of(level)
        for k in range(bisect.bisect_right(times, after), len(times)):
            if directions[k] == direction:
                return times[k]
        return np.inf


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


def idle_currents(schedule: StepSchedule, sequencer: Sequencer, end: float, start: float = 0.0):
    """Reference currents with idle current reduction, as a piecewise-constant signal.

    The drive holds the full current from each step (and from ``start``) for
    ``sequencer.idle_delay`` seconds, then ``idle_current_fraction`` of it until the next step.

    Parameters
    ----------
    schedule : StepSchedule
    sequencer : Sequencer
    end : float  [s]
        End of the window.
    start : float, default 0  [s]

    Returns
    -------
    times, current_a, current_b : arrays  [s], [A], [A]
        The currents hold from ``times[k]`` until ``times[k + 1]`` (the last until ``end``).
    """
    steps = schedule.times[(schedule.times > start) & (schedule.times <= end)]
    indices = schedule.index_at(np.concatenate([[start], steps]))
    full_a, full_b = sequencer.reference_currents(indices)
    starts = np.concatenate([[start], steps])
    stops = np.concatenate([steps, [end]])
    times, i_a, i_b = [], [], []
    f = sequencer.idle_current_fraction
    for t0, t1, a, b in zip(starts, stops, full_a, full_b):
        times.append(t0)
        i_a.append(a)
        i_b.append(b)
        drop = t0 + sequencer.idle_delay
        if f < 1.0 and drop < t1:
            times.append(drop)
            i_a.append(f * a)
            i_b.append(f * b)
    return np.array(times), np.array(i_a), np.array(i_b)


def holding_energy(times, current_a, current_b, end: float, resistance: float) -> float:
    """Copper energy R (i_a^2 + i_b^2) integrated over a piecewise-constant current signal [J].

    Parameters
    ----------
    times, current_a, current_b : array-like
        As returned by :func:`idle_currents` [s], [A], [A].
    end : float  [s]
    resistance : float  [ohm]
        Phase resistance R ([paper], Table 3: 0.1 ohm).
    """
    times = np.asarray(times, dtype=float)
    durations = np.diff(np.concatenate([times, [end]]))
    power = resistance * (np.asarray(current_a) ** 2 + np.asarray(current_b) ** 2)  # Joule's law, R i^2 per phase
    return float(np.sum(power * durations))


def stuck_currents(times: np.ndarray, values: list[np.ndarray], span: tuple[float, float] | None):
    """Phase-current changes of a driver stuck over ``span`` (start, end) [s]: the changes in it are dropped,
    and where any was, the currents then in force are applied at its end (the driver takes up the sequence
    where it stands, and the rotor jumps to the nearest detent of that phase: steps are lost in whole
    electrical periods). ``times`` [s]: the changes; ``values``: arrays with one value before them, then one
    from each. Returns (times, values) the same way."""
    if span is None:
        return times, values
    times = np.asarray(times, dtype=float)
    first = int(np.searchsorted(times, span[0], side="left"))  # the changes first:cut are in the span
    cut = int(np.searchsorted(times, span[1], side="left"))
    if cut == first:
        return times, values
    kept = [
        np.concatenate([value[: first + 1], [value[cut]], value[cut + 1 :]])  # value[cut]: from the last dropped on
        for value in (np.asarray(v, dtype=float) for v in values)
    ]
    return np.concatenate([times[:first], [span[1]], times[cut:]]), kept
