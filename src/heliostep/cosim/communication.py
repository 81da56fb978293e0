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

from heliostep.cosim.connections import split_name
from heliostep.cosim.events import Terminated
from heliostep.cosim.outcome import Interrupted, ended
from heliostep.cosim.rows import RowBuffer
from heliostep.cosim.sampled import SampledComponent, SampledSystem
from heliostep.cosim.signals import Connection

__all__ = ["CommunicationLoop"]

#: rows written before the block is handed on (at most the sink's ``sink_rows``)
BLOCK_ROWS = 4096


class Run(Protocol):
    """What the loop needs of the master's run (:class:`heliostep.cosim.master._Run`)."""

    time: float

    @property
    def rows(self) -> RowBuffer: ...

    @property
    def monitor(self) -> Callable[[np.ndarray], None] | None: ...

    @property
    def progress(self) -> Callable[[float], None] | None: ...

    @property
    def should_stop(self) -> Callable[[], bool] | None: ...

    @property
    def counts(self) -> dict[str, int]: ...


class _Bound:
    """A component's FMI calls bound once: its outputs' getter (into the row), its inputs' setter (from
    ``inputs``, taken from the row's columns ``sources`` and transformed as their connections say, or a slice
    of the row itself where they lie side by side there untransformed: ``sources`` None), and whether it
    stepped at the last point."""

    __slots__ = ("component", "get", "put", "inputs", "sources", "factors", "offsets", "stepped")

    def __init__(self, component: SampledComponent, row: np.ndarray, columns: list[str], ends: list[Connection]):
        instance, outputs = component.instance, component.outputs
        assert instance is not None
        self.component, self.stepped = component, False
        self.get: Callable[[], None] | None = None
        if outputs:
            first = columns.index(f"{component.name}.{outputs[0]}")
            assert columns[first : first + len(outputs)] == [f"{component.name}.{v}" for v in outputs]
            held = row[first : first + len(outputs)]
            held[:] = [component.held[v] for v in outputs]
            self.get = instance.real_getter(outputs, held)
        sources = [columns.index(c.source) for c in ends]
        self.sources: np.ndarray | None = np.array(sources, dtype=np.intp)
        self.inputs = np.zeros(len(ends))
        transforms = [c.transform if c.transform is not None else (1.0, 0.0) for c in ends]
        self.factors: np.ndarray | None = np.array([f for f, _ in transforms])
        self.offsets = np.array([o for _, o in transforms])
        if all(t == (1.0, 0.0) for t in transforms):  # (as copied: no product, no sum, the sign of a zero kept)
            self.factors = None
            if sources and sources == list(range(sources[0], sources[0] + len(sources))):  # set from the row as it is
                self.inputs, self.sources = row[sources[0] : sources[0] + len(sources)], None
        targets = [split_name(c.target, "target")[1] for c in ends]
        self.put: Callable[[], None] | None = instance.real_setter(targets, self.inputs) if ends else None

    def set_inputs(self, row: np.ndarray) -> None:
        """The inputs set from the outputs held in ``row`` (``factor * value + offset``: the product rounded first)."""
        if self.put is None:
            return
        if self.sources is not None:
            row.take(self.sources, out=self.inputs)
            if self.factors is not None:
                np.multiply(self.inputs, self.factors, out=self.inputs)
                np.add(self.inputs, self.offsets, out=self.inputs)
        self.put()


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
        self.parts: list[_Bound] = []

    def _bind(self) -> None:
        """Every component's FMI calls bound onto the row and its inputs; every input set (the start)."""
        columns = self.run.rows.columns
        for name, component in self.sampled.components.items():
            ends = [c for c in self.sampled.connections if split_name(c.target, "target")[0] == name]
            self.parts.append(_Bound(component, self.row, columns, ends))
        for part in self.parts:
            part.set_inputs(self.row)

    def communicate(self, t: float) -> Terminated | None:
        """At a communication point ``t`` [s]: the components due step to it with the inputs they held and their
        outputs are read, then their inputs set; what ends the run there if one asked to terminate, else None."""
        if t == self.communicated:
            return None
        self.communicated = t
        stop: list[str] | None = None  # the components that asked to terminate (a list only then)
        for part in self.parts:
            component = part.component
            part.stepped = component.due(t)
            if part.stepped:
                if component.step(t):
                    stop = [*(stop or []), component.name]
                if part.get is not None:
                    part.get()
        row = self.row
        for part in self.parts:
            if part.stepped:
                part.set_inputs(row)
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
            ended(self.run, stop)
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
