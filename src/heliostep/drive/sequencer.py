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

from heliostep.drive.crossings import STOP_CHECK_STEPS, LevelCrossings, PreparationStopped
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
    crossings = LevelCrossings(reference)
    first, ups, downs = crossings.lattice(sequencer, TRIGGERS[trigger] * sequencer.increment)
    levels = np.unique(np.concatenate([ups, downs]))
    up_level, down_level = np.searchsorted(levels, ups), np.searchsorted(levels, downs)  # each found exactly
    wanted = np.zeros((len(levels), 2), dtype=bool)  # per level: a step's if crossed upwards, downwards
    wanted[up_level, 0] = wanted[down_level, 1] = True
    times, directions, bounds = crossings.solve(levels, wanted, should_stop)
    steps = _possible_steps(np.arange(first, first + len(ups)), (up_level, down_level), times, directions, bounds)
    step_times, step_indices = _walk(steps, initial_index, start, should_stop)
    return StepSchedule(step_times, step_indices, initial_index)


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
