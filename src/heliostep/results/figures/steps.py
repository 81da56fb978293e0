"""Judging a run's steps: each step's outcome, the figures of the steps, the steps lost.

:class:`StepJudge` judges each step once the row at the next step is reached, holding one step
interval's rows; the definitions are those of :mod:`heliostep.results.figures.summary`.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Literal, NamedTuple

import numpy as np

from heliostep.drive.sequencer import Sequencer, StepSchedule

__all__ = [
    "FULL_STEPS_PER_PERIOD",
    "MISS_TOLERANCE",
    "SETTLING_BAND",
    "JudgedSteps",
    "Settling",
    "StepJudge",
    "StepOutcome",
    "held_lag",
    "judged_steps",
    "lost_between",
    "lost_steps",
    "outcome_records",
    "rest_detent",
    "step_outcome",
]

#: Band around the rest position that counts as settled, in step increments.
SETTLING_BAND = 0.05
#: A step is missed when the rotor's move differs from the increment by more than this [increments].
MISS_TOLERANCE = 0.5
#: Full steps per electrical period (2 pi / N_c): a slipping rotor falls back by multiples of it.
FULL_STEPS_PER_PERIOD = 4


class StepOutcome(NamedTuple):
    """One commanded step, judged."""

    time_s: float  # the step's instant [s]
    commanded: float | None  # the commanded rotor angle [rad] (None: read back from a stored record)
    missed: bool
    settling_s: float | None  # from the step until settled [s]; None: not settled by the next step (or the end)
    move_steps: float  # the rotor's move from the step to the next step (or the end) [increments]

    def record(self) -> dict:
        """As stored in ``metadata['solution_figures']['step_outcomes']``."""
        return {
            "time_s": self.time_s,
            "missed": self.missed,
            "settling_s": self.settling_s,
            "move_steps": self.move_steps,
        }

    @classmethod
    def from_record(cls, record: Mapping) -> StepOutcome:
        return cls(record["time_s"], None, record["missed"], record["settling_s"], record["move_steps"])


@dataclass(frozen=True)
class Settling:
    """Settling times of the steps judged [s]."""

    max: float | None
    mean: float | None
    not_settled: int
    per_step: list[float | None]

    def record(self) -> dict:
        return {"max": self.max, "mean": self.mean, "not_settled": self.not_settled, "per_step": self.per_step}


@dataclass(frozen=True)
class JudgedSteps:
    """What the outcomes of the steps judged say: missed and executed steps, settling."""

    missed_steps: int
    steps_executed: int
    settling_time_s: Settling
    missed_step_times_s: list[float]


def judged_steps(outcomes: Sequence[StepOutcome], commanded: int) -> JudgedSteps:
    """The figures of ``outcomes`` of ``commanded`` steps."""
    missed = [o for o in outcomes if o.missed]
    settling = [o.settling_s for o in outcomes]
    settled = [s for s in settling if s is not None]
    return JudgedSteps(
        len(missed),
        commanded - len(missed),
        Settling(
            max(settled) if settled else None,
            float(np.mean(settled)) if settled else None,
            sum(1 for s in settling if s is None),
            settling,
        ),
        [o.time_s for o in missed],
    )


def held_lag(start_lag: float, current_fraction: float, sequencer: Sequencer) -> float:
    """The elastic lag [rad] under the same load when the holding current has fallen to
    ``current_fraction`` of the current that held ``start_lag`` [rad] (idle current reduction).

    A detent holds the load with the torque k_e I sin(N_c δ) ([paper], eq. 9; one full step is a
    quarter of the electrical period 2π/N_c), so sin(N_c δ_end) = sin(N_c δ_start) / fraction;
    past the pull-out point (a ratio above 1) the lag is one full step, where the rotor slips.
    """
    quarter = np.pi / 2 / sequencer.step_angle  # N_c
    ratio = np.sin(quarter * start_lag) / current_fraction
    return float(np.arcsin(np.clip(ratio, -1.0, 1.0)) / quarter)


def _end_current_fraction(sequencer: Sequencer, schedule: StepSchedule, start: float, end: float) -> float:
    """The fraction of the full current the drive holds at ``end`` (see
    :func:`heliostep.drive.sequencer.idle_currents`)."""
    steps = schedule.times[(schedule.times > start) & (schedule.times <= end)]
    last = float(steps[-1]) if len(steps) else start
    return sequencer.idle_current_fraction if end - last > sequencer.idle_delay else 1.0


def lost_steps(
    behind: float, start_lag: float, sequencer: Sequencer, schedule: StepSchedule, start: float, end: float
) -> tuple[int, float]:
    """(steps lost, elastic lag left) [increments] from how far the rotor ends behind the command
    and the lag it held at the start (both [increments]): the lost steps are net of the elastic
    lag the load causes at the end, at the holding current of the end (:func:`held_lag`)."""
    increment = sequencer.increment
    fraction = _end_current_fraction(sequencer, schedule, start, end)
    lag = start_lag if fraction == 1.0 else held_lag(start_lag * increment, fraction, sequencer) / increment
    lost = int(np.round(behind - lag))
    return lost, float(behind - lost)


def lost_between(
    first: tuple[float, float],
    last: tuple[float, float],
    last_time_repeated: bool,
    sequencer: Sequencer,
    schedule: StepSchedule,
) -> tuple[int, float]:
    """:func:`lost_steps` of rows from ``first`` to ``last`` (each (time [s], rotor angle [rad])):
    the command at the first row is the one before a step at its time, at the last row the one
    after it when the row before it has the same time (a step's second row)."""
    start, end = first[0], last[0]
    first_cmd = float(sequencer.position(schedule.index_at(np.array([start]), side="left"))[0])
    side: Literal["left", "right"] = "right" if last_time_repeated else "left"
    last_cmd = float(sequencer.position(schedule.index_at(np.array([end]), side=side))[0])
    increment = sequencer.increment
    behind = (last_cmd - float(last[1])) / increment
    lag = (first_cmd - float(first[1])) / increment
    return lost_steps(behind, lag, sequencer, schedule, start, end)


def _period(sequencer: Sequencer) -> float:
    """One electrical period of the rotor [rad]: 4 full steps."""
    return FULL_STEPS_PER_PERIOD * sequencer.step_angle


def rest_detent(commanded, lag, rotor_end, sequencer: Sequencer):
    """The rotor's rest [rad] a step is judged about: the command ``commanded`` less the elastic ``lag`` held at
    the first row, moved by whole electrical periods to the detent the rotor ends in at ``rotor_end`` [rad]."""
    period = _period(sequencer)
    rest = commanded - lag
    return rest - period * np.round((rest - rotor_end) / period)


def step_outcome(
    t_step: float,
    commanded: float,
    previous: float,
    t: np.ndarray,
    x: np.ndarray,
    lag: float,
    sequencer: Sequencer,
    settling_band: float = SETTLING_BAND,
) -> StepOutcome:
    """One step's outcome from the rows ``t, x`` of the rotor from the row at the step to the row
    at the next step (or the end), both included; ``previous`` is the command before the step
    and ``lag`` the elastic lag held at the start [rad]."""
    increment = sequencer.increment
    move = (x[-1] - x[0]) / increment
    missed = bool(abs(move - (commanded - previous) / increment) > MISS_TOLERANCE)
    rest = rest_detent(commanded, lag, x[-1], sequencer)
    outside = np.nonzero(np.abs(x - rest) > settling_band * increment)[0]
    settling: float | None
    if len(outside) == 0:
        settling = 0.0
    elif outside[-1] == len(x) - 1:
        settling = None
    else:
        j = outside[-1]  # last row outside the band; the crossing lies between j and j + 1
        band = settling_band * increment
        d0, d1 = abs(x[j] - rest) - band, abs(x[j + 1] - rest) - band
        fraction = d0 / (d0 - d1) if d0 != d1 else 1.0
        settling = float(t[j] + fraction * (t[j + 1] - t[j]) - t_step)
    return StepOutcome(float(t_step), commanded, missed, settling, float(move))


class StepJudge:
    """Each step's outcome from the rotor's rows (time order, in blocks of any size): a step is
    judged once the first row at (or after) the next step is taken, from the rows between (both
    included); the last step lasts to the end. Only the rotor's rows of the step not yet judged
    are held (``max_held``: the most at once)."""

    def __init__(self, sequencer: Sequencer, schedule: StepSchedule) -> None:
        self.sequencer, self.schedule = sequencer, schedule
        self._k = 0  # the next step to judge
        self._open = False  # its first row (the row at the step) has been seen
        self._step_t: list[np.ndarray] = []
        self._step_x: list[np.ndarray] = []
        self._previous = float(sequencer.position(schedule.initial_index))
        self.lag: float | None = None  # the elastic lag held at the first row [rad]
        self.outcomes: list[StepOutcome] = []
        self.max_held = 0  # the most rotor rows held at once for a step not yet judged

    def __call__(self, time: np.ndarray, rotor: np.ndarray) -> None:
        """Take the next rows (a block of times [s] and rotor angles [rad])."""
        if self.lag is None:
            self.lag = float(self.sequencer.position(self.schedule.initial_index) - rotor[0])
        try:
            self._judge_steps(time, rotor)
        finally:
            self.max_held = max(self.max_held, sum(len(t) for t in self._step_t))

    def _judge_steps(self, time: np.ndarray, rotor: np.ndarray) -> None:
        times, n, pos = self.schedule.times, len(self.schedule), 0
        while self._k < n:
            if not self._open:
                pos += int(np.searchsorted(time[pos:], times[self._k], side="left"))
                if pos == len(time):
                    return
                self._open = True
            if self._k + 1 == n:  # the last step lasts to the end of the run
                self._step_t.append(time[pos:])
                self._step_x.append(rotor[pos:])
                return
            if not self._step_t:  # the steps that begin and end in this block: judged at once
                judged = self._judge_within(time, rotor, pos)
                if judged is not None:
                    pos = judged
                    continue
            last = pos + int(np.searchsorted(time[pos:], times[self._k + 1], side="left"))
            if last == len(time):
                self._step_t.append(time[pos:])
                self._step_x.append(rotor[pos:])
                return
            self._step_t.append(time[pos : last + 1])
            self._step_x.append(rotor[pos : last + 1])
            self.max_held = max(self.max_held, sum(len(t) for t in self._step_t))
            outcome = self._outcome(np.concatenate(self._step_t), np.concatenate(self._step_x))
            if outcome.commanded is None:  # an outcome judged here has its command; only a stored record has not
                raise RuntimeError(f"the step at {outcome.time_s} s was judged without its command")
            self.outcomes.append(outcome)
            self._previous = outcome.commanded
            self._k += 1
            self._open = False
            self._step_t, self._step_x = [], []
            pos = last

    def _judge_within(self, time: np.ndarray, rotor: np.ndarray, pos: int) -> int | None:
        """Judge the open step (its rows from ``pos`` on) and those after it that end within the
        block, as :func:`step_outcome` judges one, operation for operation on arrays: returns the
        first row of the step then open (None: none ends here)."""
        times, k = self.schedule.times, self._k
        ends = np.searchsorted(time, times[k + 1 :], side="left")
        m = int(np.searchsorted(ends, len(time), side="left"))  # steps k .. k + m - 1 end here
        if m == 0 or self.lag is None:
            return None
        starts = np.concatenate([[pos], ends[: m - 1]])
        stops = ends[:m]
        sequencer, increment = self.sequencer, self.sequencer.increment
        band = SETTLING_BAND * increment
        commanded = np.asarray(sequencer.position(self.schedule.indices[k : k + m]), dtype=float)
        previous = np.concatenate([[self._previous], commanded[:-1]])
        move = (rotor[stops] - rotor[starts]) / increment
        missed = np.abs(move - (commanded - previous) / increment) > MISS_TOLERANCE
        rest = rest_detent(commanded, self.lag, rotor[stops], sequencer)
        lengths = stops - starts + 1  # each step's rows: its first to the next step's first, both included
        offsets = np.cumsum(lengths) - lengths
        local = np.arange(int(lengths.sum())) - np.repeat(offsets, lengths)
        rows = np.repeat(starts, lengths) + local
        outside = np.abs(rotor[rows] - np.repeat(rest, lengths)) > band
        last = np.maximum.reduceat(np.where(outside, local, -1), offsets)  # each step's last row outside
        j = starts + np.maximum(last, 0)
        following = np.minimum(j + 1, len(time) - 1)
        d0, d1 = np.abs(rotor[j] - rest) - band, np.abs(rotor[following] - rest) - band
        with np.errstate(divide="ignore", invalid="ignore"):
            fraction = np.where(d0 != d1, d0 / (d0 - d1), 1.0)
        settling = time[j] + fraction * (time[following] - time[j]) - times[k : k + m]
        for i in range(m):
            settled = 0.0 if last[i] < 0 else None if last[i] == lengths[i] - 1 else float(settling[i])
            self.outcomes.append(
                StepOutcome(float(times[k + i]), float(commanded[i]), bool(missed[i]), settled, float(move[i]))
            )
        self.max_held = max(self.max_held, int(lengths.max()))
        self._previous = float(commanded[-1])
        self._k += m
        self._open = self._k < len(self.schedule)  # the next step's first row: the last step's last
        return int(stops[-1])

    def _outcome(self, t: np.ndarray, x: np.ndarray) -> StepOutcome:
        if self.lag is None:  # set by the first rows taken, before any step is judged
            raise RuntimeError("a step judged before the judge took its first rows")
        index = self.schedule.indices[self._k]
        return step_outcome(
            self.schedule.times[self._k],
            float(self.sequencer.position(index)),
            self._previous,
            t,
            x,
            self.lag,
            self.sequencer,
        )

    def outcomes_at_end(self, end: float) -> list[StepOutcome]:
        """The steps judged and the step open at the end (the last row taken, at ``end`` [s]),
        judged up to the end (the last step: up to the first row at ``end``)."""
        outcomes = list(self.outcomes)
        if self._open and self._k < len(self.schedule):
            t, x = np.concatenate(self._step_t), np.concatenate(self._step_x)
            if self._k + 1 == len(self.schedule):  # judged up to the first row at the end
                cut = int(np.searchsorted(t, end, side="left"))
                t, x = t[: cut + 1], x[: cut + 1]
            outcomes.append(self._outcome(t, x))
        return outcomes


def outcome_records(outcomes: Iterable[StepOutcome]) -> list[dict]:
    """The outcomes as stored in ``metadata['solution_figures']['step_outcomes']``."""
    return [o.record() for o in outcomes]
