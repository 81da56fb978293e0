"""A controller sampled by the master: it reads FMU outputs at its sample instants and decides, while the
system is simulated, the later changes of the master inputs it drives (a loop closed through the
co-simulation, one master).

A sample instant is a point the solver stops at without a restart (nothing changes there unless the
controller decides so); a change the controller appends, at the instant or later, is an input change
like any other, handled at its own time (in the compiled kernel where the run's events are).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Protocol

import numpy as np

if TYPE_CHECKING:
    from heliostep.cosim.system import CoupledSystem

__all__ = ["ControllerSamples", "SampledController", "ScheduledInput"]


class ScheduledInput:
    """A master input (read like :class:`~heliostep.cosim.signals.PiecewiseConstant`: ``values[0]`` before
    ``times[0]``, ``values[k + 1]`` from ``times[k]`` on) whose changes are appended while simulating.

    The changes live in buffers that grow by doubling; :attr:`buffers` gives their current arrays, whose
    addresses the compiled kernel reads (refreshed by the master after each sample that appended).
    """

    def __init__(self, name: str, target: str, initial: float, capacity: int = 256):
        self.name, self.target = name, target
        self._times = np.empty(max(1, capacity))
        self._values = np.empty(max(1, capacity) + 1)
        self._values[0] = float(initial)
        self._count = 0

    @property
    def times(self) -> np.ndarray:
        """The change instants appended so far [s]."""
        return self._times[: self._count]

    @property
    def values(self) -> np.ndarray:
        """The value before the first change, then from each change on."""
        return self._values[: self._count + 1]

    @property
    def buffers(self) -> tuple[np.ndarray, np.ndarray]:
        """The arrays the changes are kept in (times, values), valid until the next :meth:`append`."""
        return self._times, self._values

    def value_at(self, time: float) -> float:
        """Value from ``time`` on (right-continuous)."""
        return float(self._values[np.searchsorted(self.times, time, side="right")])

    def append(self, time: float, value: float) -> None:
        """A change to ``value`` from ``time`` [s] on, not before the last change appended."""
        if self._count and time < self._times[self._count - 1]:
            raise ValueError(f"input {self.name}: a change at {time!r} s before the last one appended")
        if self._count == len(self._times):
            self._times = np.concatenate([self._times, np.empty(len(self._times))])
            self._values = np.concatenate([self._values, np.empty(len(self._times) - len(self._values) + 1)])
        self._times[self._count] = time
        self._values[self._count + 1] = value
        self._count += 1


class SampledController(Protocol):
    """What the master asks of a controller (``CoSimulation(..., controller=...)``).

    Attributes
    ----------
    sample_times : ndarray
        The instants it samples at [s], increasing (those in the run's window are used).
    reads : sequence of str
        The FMU outputs it reads at each sample, as ``instance.variable``.
    inputs : sequence of ScheduledInput
        The master inputs it drives (traced as the others are).
    sets : sequence of str
        FMU inputs it gives at the start and at each sample before reading (:meth:`setting`), without an
        event: each must belong to an FMU with no continuous state whose outputs feed no other FMU, so
        that no derivative sees the change (what a sensor's view of the sun is).
    """

    sample_times: np.ndarray
    reads: Sequence[str]
    inputs: Sequence[ScheduledInput]
    sets: Sequence[str]

    def setting(self, time: float) -> np.ndarray:
        """The values of :attr:`sets` at ``time`` [s]."""
        ...

    def sample(self, time: float, readings: np.ndarray) -> None:
        """At the sample instant ``time`` [s], with the outputs :attr:`reads` there: append the changes
        decided to :attr:`inputs` (at ``time`` or later)."""
        ...

    def outputs_after(self, time: float) -> np.ndarray:
        """The output rows [s] wanted for the changes decided at the sample ``time`` (the run's grid gets
        those later than ``time``)."""
        ...


class ControllerSamples:
    """A run's sample instants of its controller in the window (none without one), and the samples taken."""

    def __init__(self, controller: SampledController | None, system: CoupledSystem, start: float, stop: float):
        self.controller = controller
        times = np.zeros(0) if controller is None else np.asarray(controller.sample_times, dtype=float)
        self.times = times[(times > start) & (times <= stop)]
        self.k = 0
        self.readers: list[Callable[[], np.ndarray]] = []
        self.writers: list[Callable[[list[float]], None]] = []
        self._before: list[int] = []
        if controller is not None:
            for name in controller.reads:
                instance, variable = name.split(".", 1)
                self.readers.append(system.units[instance].fmu.reader([variable]))
            for name in controller.sets:
                instance, variable = name.split(".", 1)
                self.writers.append(system.units[instance].fmu.writer([variable]))
            self.give(start)

    def give(self, t: float) -> None:
        """The controller's :attr:`~SampledController.sets` at ``t``."""
        assert self.controller is not None
        for write, value in zip(self.writers, self.controller.setting(t)):
            write([float(value)])

    @property
    def next_time(self) -> float:
        return float(self.times[self.k]) if self.k < len(self.times) else np.inf

    def due(self, t: float) -> bool:
        return self.k < len(self.times) and self.times[self.k] <= t + 1e-12 * max(1.0, abs(t))

    def take(self, t: float) -> bool:
        """The controller sampled at ``t`` (the system's outputs there); whether it appended changes."""
        assert self.controller is not None
        while self.due(t):
            self.k += 1
        before = [len(item.times) for item in self.controller.inputs]
        self.give(t)
        readings = np.array([float(read()[0]) for read in self.readers])
        self.controller.sample(t, readings)
        self._before = before
        return any(len(item.times) != n for item, n in zip(self.controller.inputs, before))

    def changes_after(self, t: float) -> np.ndarray:
        """The change instants appended at the last sample (at ``t`` or later)."""
        assert self.controller is not None
        added = np.concatenate([item.times[n:] for item, n in zip(self.controller.inputs, self._before)])
        if np.any(added < t - 1e-12 * max(1.0, abs(t))):
            raise RuntimeError(f"the controller sampled at t = {t:.9g} s appended a change before that instant")
        return added

    def outputs_after(self, t: float, grid: np.ndarray, stop: float) -> np.ndarray:
        """The output times still to come (``grid``, increasing) with those the controller wants for the
        changes it decided at ``t``, up to ``stop``."""
        assert self.controller is not None
        wanted = np.asarray(self.controller.outputs_after(t), dtype=float)
        wanted = wanted[(wanted > t) & (wanted <= stop)]
        return np.union1d(grid, wanted) if len(wanted) else grid
