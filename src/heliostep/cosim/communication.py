"""The master's loop for a system of Co-Simulation FMUs alone: its communication points, nothing to integrate.

With no Model Exchange FMU (no continuous state, no event to locate) and no controller, a run is its sampled
components' communication points (:mod:`heliostep.cosim.sampled`): at each, the row before, every component
due stepped (``DoStep``) and its outputs read, then the inputs of those stepped set from the outputs held
(Jacobi), the row after; an output time between points gives a row of the outputs held. The FMI calls are
bound once onto one vector, the row (time and every output held), and the rows written into a block handed
on whole. The times, rows, failures and terminations are those the Model Exchange master's loop gives the
same system (:mod:`heliostep.cosim.master`): one master, this its loop where there is nothing to integrate.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Protocol

import numpy as np

from heliostep.cosim.events import Terminated
from heliostep.cosim.outcome import Interrupted
from heliostep.cosim.rows import RowBuffer
from heliostep.cosim.sampled import SampledComponent, SampledSystem

__all__ = ["CommunicationLoop"]

#: rows written before the block is handed on (at most the sink's ``sink_rows``)
BLOCK_ROWS = 4096


class Run(Protocol):
    """What the loop needs of the master's run (:class:`heliostep.cosim.master._Run`)."""

    rows: RowBuffer
    monitor: Callable[[np.ndarray], None] | None
    progress: Callable[[float], None] | None
    should_stop: Callable[[], bool] | None
    time: float
    counts: dict[str, int]

    def ended(self, stop: Terminated) -> None:
        """Note that the run ended normally at ``stop.time`` because an FMU asked to terminate."""


class CommunicationLoop:
    """The run of ``sampled`` (every FMU of the system) from its start to its stop time, output rows at ``grid``."""

    def __init__(self, run: Run, sampled: SampledSystem):
        self.run, self.sampled = run, sampled
        columns = run.rows.columns
        self.row = np.zeros(len(columns))  # time, then every output held: the row as the trace lays it out
        size = BLOCK_ROWS if run.rows.sink is None else min(BLOCK_ROWS, run.rows.sink_rows)
        self.block = np.empty((size, len(columns)))
        self.filled = 0
        self.communicated = np.nan  # the last time communicated (asked again there: nothing due)
        #: per component: it, its outputs' getter (into the row), its inputs' setter, the columns they are read from
        self.parts: list[tuple[SampledComponent, Callable[[], None] | None, Callable[[], None] | None, np.ndarray]] = []
        self.inputs: dict[str, np.ndarray] = {}

    def _bind(self) -> None:
        """Every component's FMI calls bound onto the row (its outputs' columns, the held values there) and
        onto a vector of its inputs; every input set (the start)."""
        columns = self.run.rows.columns
        for component in self.sampled.components.values():
            assert component.instance is not None
            instance, outputs, getter = component.instance, component.outputs, None
            if outputs:
                first = columns.index(f"{component.name}.{outputs[0]}")
                assert columns[first : first + len(outputs)] == [f"{component.name}.{v}" for v in outputs]
                values = self.row[first : first + len(outputs)]
                values[:] = [component.held[v] for v in outputs]
                getter = instance.real_getter(outputs, values)
            ends = [c for c in self.sampled.connections if c.target.split(".", 1)[0] == component.name]
            sources = np.array([columns.index(c.source) for c in ends], dtype=np.intp)
            inputs = self.inputs[component.name] = np.zeros(len(ends))
            setter = instance.real_setter([c.target.split(".", 1)[1] for c in ends], inputs) if ends else None
            self.parts.append((component, getter, setter, sources))
        for component, _, setter, sources in self.parts:
            if setter is not None:
                np.take(self.row, sources, out=self.inputs[component.name])
                setter()

    def communicate(self, t: float) -> Terminated | None:
        """At a communication point ``t`` [s]: the components due step to it with the inputs they held and their
        outputs are read, then their inputs set; what ends the run there if one asked to terminate, else None."""
        if t == self.communicated:
            return None
        self.communicated = t
        due = [part for part in self.parts if part[0].due(t)]
        stop = [part[0].name for part in due if part[0].step(t)]
        for _, getter, _, _ in due:
            if getter is not None:
                getter()
        inputs = self.inputs
        for component, _, setter, sources in due:
            if setter is not None:
                np.take(self.row, sources, out=inputs[component.name])
                setter()
        return self.sampled.terminated(stop, t) if stop else None

    def record(self, t: float) -> None:
        """The row at ``t`` [s] (the outputs held) into the block; a full block handed on."""
        row = self.row
        row[0] = t
        self.block[self.filled] = row
        self.filled += 1
        if self.filled == len(self.block):
            self.flush()

    def flush(self) -> None:
        """The rows written since the last flush to the monitor and the trace."""
        if self.filled:
            rows = self.block[: self.filled]
            self.filled = 0
            if self.run.monitor is not None:
                self.run.monitor(rows)
            self.run.rows.store(rows.copy())

    def event(self, t: float) -> bool:
        """The communication at ``t`` [s] between its row before and its row after; whether it ends the run."""
        self.run.counts["events"] += 1
        self.record(t)
        stop = self.communicate(t)
        self.record(t)
        if stop is not None:
            self.run.ended(stop)
        return stop is not None

    def execute(self, start_time: float, stop_time: float, grid: np.ndarray) -> None:
        """The run: the components started and their inputs set, the row at ``start_time``, then every stop."""
        run = self.run
        run.time = start_time
        try:
            self.sampled.start(start_time, stop_time)
            self._bind()
            self.record(start_time)
            self._loop(start_time, stop_time, grid)
        finally:
            self.flush()

    def _loop(self, start_time: float, stop_time: float, grid: np.ndarray) -> None:
        """From ``start_time`` to ``stop_time`` [s]: a row at each output time of ``grid`` and the two rows of each
        communication point, the stops in the order and with the rounding of the Model Exchange master's loop."""
        run, record, event = self.run, self.record, self.event
        points = np.unique(np.concatenate([c.times for c in self.sampled.components.values()]))
        changes = points[(points > start_time) & (points <= stop_time)].tolist()
        outputs = grid.tolist()
        n_changes, n_outputs = len(changes), len(outputs)
        progress, should_stop = run.progress, run.should_stop
        t = start_time
        next_output = next_change = 0
        while True:
            eps = 1e-12 * max(1.0, abs(t))  # stops closer than this to t count as reached
            while next_output < n_outputs and outputs[next_output] <= t + eps:
                next_output += 1
            if next_change < n_changes and changes[next_change] <= t + eps:  # a point a rounding error after t
                next_change += 1
                if event(t):
                    return
                continue
            if t >= stop_time - eps:
                return
            t_output = outputs[next_output] if next_output < n_outputs else stop_time
            t_change = changes[next_change] if next_change < n_changes else np.inf
            t = run.time = min(t_output, t_change, stop_time)
            if t >= t_change:
                next_change += 1
                if event(t):
                    return
            elif t >= t_output:
                record(t)
            if progress is not None:
                progress(t)
            if should_stop is not None and should_stop():
                raise Interrupted()
