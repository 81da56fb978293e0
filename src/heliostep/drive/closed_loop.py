"""Closed-loop tracking: a controller that samples the sun sensor and steps the drive on what it sees.

The controller is a :class:`~heliostep.cosim.controller.SampledController`: every ``sample_period`` it
gives the sensor its view of the sun (the ideal panel angle, DNI, diffuse, the reading's noise), reads the
sensor's signal, and appends the steps it decides to the phase-current inputs of the motor, so its steps
enter the drive as the open-loop ones do. Modes:

- ``closed_loop``: on a lit sensor whose error estimate is beyond the dead band, steps towards balance (as
  many as the estimate asks, or a fixed move, seed 001's Δβ); dark, it holds. A reading while the last
  move is still being stepped decides nothing.
- ``hybrid``: the open-loop schedule (the astronomical reference), shifted by a correction the lit sensor
  adjusts as ``closed_loop`` does; dark, it follows the reference with the correction it had.

Details: docs/tracking.md.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from heliostep.drive.sequencer import Sequencer, StepSchedule

__all__ = ["ChangeLog", "DecidedSchedule", "LoopLaw", "SensorView", "TrackingLoop", "realized_schedule"]

#: The traced master input that carries the commanded step index (it drives no FMU).
STEP_INDEX = "step_index"


class ChangeLog(Protocol):
    """A master input whose changes the controller appends while simulating (the master's
    :class:`~heliostep.cosim.controller.ScheduledInput`)."""

    @property
    def times(self) -> np.ndarray: ...

    @property
    def values(self) -> np.ndarray: ...

    def append(self, time: float, value: float) -> None: ...


class DecidedSchedule(StepSchedule):
    """The steps a controller has decided so far, read from its step-index input (``log``) at each look:
    a schedule that grows while simulating. Steps decided for one instant count as one, to the last index
    (the input's value from that instant on)."""

    log: ChangeLog

    def __init__(self, log: ChangeLog, initial_index: int):
        object.__setattr__(self, "log", log)
        object.__setattr__(self, "initial_index", int(initial_index))
        object.__setattr__(self, "_cache", (-1, np.zeros(0), np.zeros(0, dtype=int)))

    def _read(self) -> tuple[np.ndarray, np.ndarray]:
        count, times, indices = self._cache  # type: ignore[attr-defined]
        if count != len(self.log.times):
            times, values = self.log.times.copy(), self.log.values[1:]
            last = np.append(times[1:] != times[:-1], True)[: len(times)]  # the last change of each instant
            times, indices = times[last], np.rint(values[last]).astype(int)
            object.__setattr__(self, "_cache", (len(self.log.times), times, indices))
        return times, indices

    @property
    def times(self) -> np.ndarray:
        return self._read()[0]

    @property
    def indices(self) -> np.ndarray:
        return self._read()[1]


@dataclass(frozen=True)
class LoopLaw:
    """How the controller steps on what the sensor says.

    Attributes
    ----------
    mode : {'closed_loop', 'hybrid'}
    sample_period : float
        Between two readings of the sensor [s].
    dead_band : float
        Panel-angle error [rad] the controller leaves alone.
    step_rate : float
        Rate of the steps it commands [sequencer increments/s].
    latency : float
        From a reading to the first step it commands [s].
    move : float or None
        A fixed move per reading [rad of panel angle] (seed 001's Δβ); None: the steps the estimate asks.
    """

    mode: str
    sample_period: float
    dead_band: float
    step_rate: float
    latency: float
    move: float | None = None


@dataclass(frozen=True)
class SensorView:
    """What the controller knows of its sensor: its angle per panel angle ``k_ray`` [-] and the half field of
    view ``fov`` [rad] of its linear range."""

    k_ray: float
    fov: float


class TrackingLoop:
    """The closed-loop (or hybrid) controller of one run.

    Parameters
    ----------
    law : LoopLaw
    sequencer : Sequencer
    sensor : SensorView
    sensor_instance : str
        The FMU instance whose signal it reads.
    initial_index : int
        The step index held at the start.
    panel_of_index : callable
        Commanded panel angle [rad] of step indices (through the transmission, [paper], eq. 14).
    index_of_panel : callable
        The (real-valued) step index at which the panel stands at a panel angle [rad].
    sample_times : ndarray
        [s] from the run's start.
    views : ndarray
        What the sensor is given at the start and at each sample (a row each): the ideal panel angle [rad]
        (the sun as it is), DNI and diffuse horizontal irradiance [W/m2], the reading's noise [-].
    open_loop : StepSchedule, optional
        The astronomical schedule ``hybrid`` follows.
    stuck : (float, float), optional
        A span [s] over which the driver ignores the steps (``faults.stuck``); its end must be a sample time.
    inputs : sequence of ChangeLog
        The phase currents' references i_a, i_b [A] and the step index it commands (traced), each holding
        its value at the start.
    step_detail : ndarray, optional
        Offsets [s] after each step it decides at which the run wants output rows (the fine grid of
        ``output.step_detail``).

    Attributes
    ----------
    schedule : DecidedSchedule
        The steps decided so far.
    """

    def __init__(
        self,
        law: LoopLaw,
        sequencer: Sequencer,
        sensor: SensorView,
        sensor_instance: str,
        initial_index: int,
        panel_of_index: Callable[[float], float],
        index_of_panel: Callable[[float], float],
        sample_times: np.ndarray,
        views: np.ndarray,
        open_loop: StepSchedule | None = None,
        stuck: tuple[float, float] | None = None,
        inputs: Sequence[ChangeLog] = (),
        step_detail: np.ndarray | None = None,
    ):
        self.law, self.sequencer, self.sensor = law, sequencer, sensor
        self.panel_of_index, self.index_of_panel = panel_of_index, index_of_panel
        self.sample_times = np.asarray(sample_times, dtype=float)
        self.views = np.asarray(views, dtype=float)
        if self.views.shape != (len(self.sample_times) + 1, 4):
            raise ValueError(f"views: expected {len(self.sample_times) + 1} rows of 4, got {self.views.shape}")
        self.open_loop = open_loop if law.mode == "hybrid" else None
        self.inputs, self.stuck = tuple(inputs), stuck
        if len(self.inputs) != 3:
            raise ValueError(f"inputs: expected i_a, i_b and the step index, got {len(self.inputs)}")
        self.schedule = DecidedSchedule(self.inputs[2], initial_index)
        self.step_detail = np.zeros(0) if step_detail is None else np.asarray(step_detail, dtype=float)
        self._steps_before = 0  # the steps decided before the last sample
        self._held: tuple[float, float] | None = None  # the currents a stuck driver ignored, taken up at its end
        self._last_step, self._dropped = 0.0, False  # the drive's last step (the start) [s], its idle drop made
        self.reads = (f"{sensor_instance}.signal", f"{sensor_instance}.lit")
        self.sets = tuple(f"{sensor_instance}.{name}" for name in ("theta_ref", "dni", "dhi", "noise"))
        self.index, self.correction = initial_index, 0
        self._followed = 0  # open-loop steps taken up to (hybrid)
        self._moving_until = -np.inf  # the last step of the last move the sensor asked for [s]
        self.readings: list[tuple[float, float, float]] = []  # (time, signal, lit)
        if self.open_loop is not None:
            self._follow(0.0, self._next_sample(0.0))
        self._drop_before(self._next_sample(0.0))

    # ------------------------------------------------------------ what the master asks
    def setting(self, time: float) -> np.ndarray:
        return self.views[int(np.searchsorted(self.sample_times, time + 1e-9, side="right"))]  # its row

    def sample(self, time: float, readings: np.ndarray) -> None:
        signal, lit = float(readings[0]), float(readings[1])
        self.readings.append((time, signal, lit))
        self._steps_before = len(self.inputs[2].times)
        if self._held is not None and self.stuck is not None and time >= self.stuck[1]:
            self._take_up()
        end = self._next_sample(time)
        wanted = self._wanted_steps(signal) if lit > 0.5 and time >= self._moving_until else 0
        if self.open_loop is None:
            self._move(time + self.law.latency, wanted)
        else:
            self.correction += wanted  # hybrid: the reference's steps, shifted by the correction
            self._follow(time, end, first=(time + self.law.latency, wanted))
        self._drop_before(end)  # every later step comes at the next sample or after

    def outputs_after(self, time: float) -> np.ndarray:
        """The output rows [s] the steps decided at the last sample ask for (:attr:`step_detail` after each)."""
        steps = self.inputs[2].times[self._steps_before :]
        return (steps[:, None] + self.step_detail[None, :]).ravel()

    # ------------------------------------------------------------ the law
    def _wanted_steps(self, signal: float) -> int:
        """Steps towards balance for a reading: the panel error the signal says, beyond the dead band."""
        law, sensor = self.law, self.sensor
        ratio = float(np.clip(signal, -1.0, 1.0))
        error = float(np.arctan(ratio * np.tan(sensor.fov))) / sensor.k_ray  # panel error [rad], within the view
        if abs(error) <= law.dead_band:
            return 0
        commanded = self.panel_of_index(self.index)
        aim = commanded + (np.sign(error) * law.move if law.move is not None else error)
        return int(np.rint(self.index_of_panel(aim) - self.index))

    def _move(self, start: float, steps: int) -> None:
        """``steps`` (signed) from ``start`` at the law's rate."""
        if not steps:
            return
        direction = int(np.sign(steps))
        self._moving_until = start + (abs(steps) - 1) / self.law.step_rate
        for k in range(abs(steps)):
            self._step(start + k / self.law.step_rate, self.index + direction)

    def _follow(self, time: float, end: float, first: tuple[float, int] | None = None) -> None:
        """Hybrid: the open-loop steps up to ``end``, each shifted by the correction, after a correction move."""
        assert self.open_loop is not None
        if first is not None and first[1]:
            self._move(*first)
        times, indices = self.open_loop.times, self.open_loop.indices
        last = float(self.inputs[2].times[-1]) if len(self.inputs[2].times) else time  # after the correction
        while self._followed < len(times) and times[self._followed] <= end:
            at = max(float(times[self._followed]), last)
            self._step(at, int(indices[self._followed]) + self.correction)
            last = at
            self._followed += 1

    def _step(self, time: float, index: int) -> None:
        """The step to ``index`` at ``time``: commanded (traced), its full currents to the driver (after the
        last step's idle drop, where due before it)."""
        if index == self.index:
            return
        self._drop_before(time)
        self.index = index
        self.inputs[2].append(time, float(index))
        i_a, i_b = self.sequencer.reference_currents(index)
        self._drive(time, float(i_a), float(i_b))
        self._last_step, self._dropped = time, False

    def _drop_before(self, time: float) -> None:
        """The last step's currents dropped to their idle fraction ``idle_delay`` after it, where that comes
        before ``time`` (:func:`~heliostep.drive.sequencer.idle_currents`, the same rule)."""
        fraction, drop = self.sequencer.idle_current_fraction, self._last_step + self.sequencer.idle_delay
        if fraction < 1.0 and not self._dropped and drop < time:
            i_a, i_b = self.sequencer.reference_currents(self.index)
            self._drive(drop, float(fraction * i_a), float(fraction * i_b))
            self._dropped = True

    def _drive(self, time: float, i_a: float, i_b: float) -> None:
        """The phase currents from ``time`` on, unless the driver is stuck then: it ignores them, and takes up
        the last it ignored at the span's end (:func:`~heliostep.drive.sequencer.stuck_currents`, the same rule)."""
        if self.stuck is not None and self.stuck[0] <= time < self.stuck[1]:
            self._held = (float(i_a), float(i_b))
            return
        if self._held is not None:
            self._take_up()
        self.inputs[0].append(time, float(i_a))
        self.inputs[1].append(time, float(i_b))

    def _take_up(self) -> None:
        """The stuck driver's currents at the span's end: the last it ignored."""
        assert self.stuck is not None and self._held is not None
        held, self._held = self._held, None
        self.inputs[0].append(self.stuck[1], held[0])
        self.inputs[1].append(self.stuck[1], held[1])

    def _next_sample(self, time: float) -> float:
        k = int(np.searchsorted(self.sample_times, time + 1e-9, side="right"))
        return float(self.sample_times[k]) if k < len(self.sample_times) else np.inf


def realized_schedule(times: np.ndarray, step_index: np.ndarray, initial_index: int) -> StepSchedule:
    """The steps a controller commanded, from the traced ``step_index`` column (time order, both sides of
    each change): the instants where it changes and the index from each on."""
    times, step_index = np.asarray(times, dtype=float), np.rint(np.asarray(step_index)).astype(int)
    changes = np.flatnonzero(np.diff(step_index)) + 1
    return StepSchedule(times[changes], step_index[changes], initial_index)
