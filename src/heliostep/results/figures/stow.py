"""The stow moves of a run, judged: per move its steps commanded, missed and lost, its peak torque.

Details: docs/running.md, ``heliostep.results.figures.stow``.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import pandas as pd

from heliostep.drive.sequencer import Sequencer, StepSchedule
from heliostep.results.figures.steps import lost_between

__all__ = ["SETTLE_AFTER_MOVE", "StowMoveFigures"]

#: After a move's last step, the time [s] the rotor is given to settle before its end row is taken.
SETTLE_AFTER_MOVE = 0.05


class StowMoveFigures:
    """Per stow move: start/end time, steps commanded, missed and lost, peak |torque| [N.m]."""

    def __init__(self, metadata: Mapping, sequencer: Sequencer, schedule: StepSchedule) -> None:
        drive = metadata.get("drive", {})
        self.moves: list[dict] = [dict(m) for m in drive.get("stow_moves", [])]
        self.spans = [tuple(span) for span in drive.get("stowed_spans_s", [])]
        roles = metadata.get("roles", {})
        self.rotor, self.torque = roles.get("rotor_angle"), roles.get("torque")
        self.sequencer, self.schedule = sequencer, schedule
        self._first: list[tuple[float, float] | None] = [None] * len(self.moves)
        self._last: list[tuple[float, float, bool] | None] = [None] * len(self.moves)
        self._peak = [0.0] * len(self.moves)
        self._previous_time: float | None = None

    def __call__(self, block: pd.DataFrame) -> None:
        if not self.moves or self.rotor not in block or not len(block):
            return
        time = block["time"].to_numpy(dtype=float)
        rotor = block[self.rotor].to_numpy(dtype=float)
        repeated = np.concatenate([[time[0] == self._previous_time], time[1:] == time[:-1]])
        for k, move in enumerate(self.moves):
            start, end = float(move["start_s"]), float(move["end_s"]) + SETTLE_AFTER_MOVE
            inside = np.nonzero((time >= start) & (time <= end))[0]
            if not len(inside):
                continue
            if self._first[k] is None:
                self._first[k] = (float(time[inside[0]]), float(rotor[inside[0]]))
            j = inside[-1]
            self._last[k] = (float(time[j]), float(rotor[j]), bool(repeated[j]))
            if self.torque in block:
                self._peak[k] = max(self._peak[k], float(np.max(np.abs(block[self.torque].to_numpy()[inside]))))
        self._previous_time = float(time[-1])

    def figures(self, outcomes: Sequence[Mapping] = ()) -> dict[str, Any]:
        """``stow_moves`` (a list, one record per move) and the time off tracking, ``stowed_time_s`` [s].

        ``outcomes``: the solution's ``step_outcomes`` (``time_s``, ``missed``)."""
        records = []
        steps = self.schedule.times
        for k, move in enumerate(self.moves):
            start, end = float(move["start_s"]), float(move["end_s"])
            in_move = (steps >= start) & (steps <= end)
            missed = sum(1 for o in outcomes if start <= float(o["time_s"]) <= end and o["missed"])
            record = {
                **move,
                "steps_commanded": int(np.count_nonzero(in_move)),
                "missed_steps": int(missed),
                "steps_lost": None,
                "peak_torque_Nm": self._peak[k] if self.torque is not None else None,
            }
            first, last = self._first[k], self._last[k]
            if first is not None and last is not None:
                lost, _ = lost_between(first, last[:2], last[2], self.sequencer, self.schedule)
                record["steps_lost"] = int(lost)
            records.append(record)
        stowed = float(sum(b - a for a, b in self.spans))
        return {"stow_moves": records, "stowed_time_s": stowed}
