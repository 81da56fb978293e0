"""Open-loop stepping: the phase-current sequencer and the step scheduler.

Steps are commanded at the exact instants the reference crosses a half-step boundary (``midpoint``)
or reaches the next position (``reach``), roots of a PCHIP interpolant of the reference.

Details: docs/physics.md, ``heliostep.drive.sequencer``.
"""

from __future__ import annotations

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
        Asked every :data:`STOP_CHECK_STEPS` levels solved and steps scheduled; when True,
        :class:`PreparationStopped` is raised.

    Returns
    -------
    StepSchedule
    """
    if trigger not in TRIGGERS:
        raise InputError(f"sequencer trigger {trigger!r}: expected one of {', '.join(TRIGGERS)}")
    start = reference.x[0]
    if initial_index is None:
        initial_index = sequencer.nearest_index(float(reference(start)))
    crossings = _LevelCrossings(reference)
    first, ups, downs = crossings.lattice(sequencer, TRIGGERS[trigger] * sequencer.increment)
    levels = np.unique(np.concatenate([ups, downs]))
    up_level, down_level = np.searchsorted(levels, ups), np.searchsorted(levels, downs)  # each found exactly
    wanted = np.zeros((len(levels), 2), dtype=bool)  # per level: a step's if crossed upwards, downwards
    wanted[up_level, 0] = wanted[down_level, 1] = True
    times, directions, bounds = crossings.solve(levels, wanted, should_stop)
    steps = _possible_steps(np.arange(first, first + len(ups)), (up_level, down_level), times, directions, bounds)
    step_times, step_indices = _walk(steps, initial_index, start, should_stop)
    return StepSchedule(step_times, step_indices, initial_index)


class _LevelCrossings:
    """Where a PCHIP reference crosses levels, in which direction; each level solved once, on the pieces that
    bracket it (PCHIP is monotone on every interval), each by scipy's root finder (that of ``PPoly.solve``).

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
        self.rising, self.falling = _monotone_slopes(self.slope.c, np.diff(self.knots))

    def lattice(self, sequencer: Sequencer, step: float) -> tuple[int, np.ndarray, np.ndarray]:
        """The up and down levels (position ± ``step``) of every step index from the first to the last whose
        levels can lie within the reference's range, two more each side: (first index, ups, downs). An index
        beyond has no level in the range: no step leads to it or from it."""
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
        per level, whether steps cross it upwards, downwards; crossings no step can take may be left out."""
        which, pieces = self._pairs(levels)
        solved = self._needed(which, pieces, wanted)
        which, pieces = which[solved], pieces[solved]
        found = self._roots(pieces.tolist(), levels[which].tolist(), should_stop)
        counts = np.fromiter(map(len, found), dtype=np.intp, count=len(found))
        roots = np.concatenate(found) if found else np.zeros(0)
        level = np.repeat(which, counts)
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


def _possible_steps(index, level_of, times, directions, bounds) -> tuple[np.ndarray, ...]:
    """Every step a crossing can command: the crossings of each ``index``'s up level upwards and of its down
    level downwards (``level_of``: their levels), as (time, from index, to index, 1 for a step down)."""
    parts = []
    for levels, direction in zip(level_of, (1, -1)):
        begin, counts = bounds[levels], bounds[levels + 1] - bounds[levels]
        at = np.repeat(begin - np.cumsum(counts) + counts, counts) + np.arange(int(counts.sum()))
        source = np.repeat(index, counts)
        match = directions[at] == direction
        at, source = at[match], source[match]
        parts.append((times[at], source, source + direction, np.full(len(at), int(direction < 0))))
    return tuple(np.concatenate(field) for field in zip(*parts))


def _walk(
    steps: tuple[np.ndarray, ...], initial_index: int, start: float, should_stop: Callable[[], bool] | None
) -> tuple[np.ndarray, np.ndarray]:
    """The steps taken, as (times, indices): from ``initial_index`` at ``start``, each the first of the possible
    ``steps`` (time, from index, to index, 1 for down) from the index commanded later than the last taken (an
    up step first at a tie): each step's successor found at once, then the chain followed."""
    time, source, target, down = steps
    if not len(time):
        return np.zeros(0), np.zeros(0, dtype=int)
    order = np.lexsort((down, time, source))
    time, source, target = time[order], source[order], target[order]
    distinct = np.unique(time)
    rank = np.searchsorted(distinct, time)
    base, width = int(source[0]), len(distinct) + 1
    key = (source - base) * width + rank  # sorted: by index, then time
    asked = np.append(target, initial_index)  # the index after each step, and at the start
    later = np.append(rank + 1, np.searchsorted(distinct, start, side="right"))  # the rank of the first time after
    found = np.searchsorted(key, (asked - base) * width + later)
    inside = np.minimum(found, len(key) - 1)
    following = np.where((found < len(key)) & (source[inside] == asked), found, -1).tolist()
    taken, step = [], following[-1]
    while step >= 0:
        taken.append(step)
        step = following[step]
        if should_stop is not None and len(taken) % STOP_CHECK_STEPS == 0 and should_stop():
            at = time[taken[-1]]
            raise PreparationStopped(f"stopped while scheduling the steps ({len(taken)} so far, t = {at:.6g} s)")
    return time[taken].astype(float), target[taken].astype(int)


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
