"""The sizing sheet's speed-torque curves and its days' step families co-simulated on every core.

Each curve is a set of bench simulations independent of the others', so the curves (each candidate's,
nominal and at the ranges' worst corner) go to a pool of processes started by the standard library's fork
server, one curve a task; a curve is the same whichever process computes it. So do the step families of
:mod:`heliostep.sizing.composed`, a family and its days a task, and the days co-simulated in full, a day a task.
The children ignore SIGINT: a stop request is the parent's, which begins no task more and keeps those under way
once finished. A script that calls the sizing needs ``if __name__ == "__main__":`` around it, as any user of
multiprocessing's fork server does (its children import the script's main module).
"""

from __future__ import annotations

import multiprocessing
import os
import signal
from collections.abc import Callable, Hashable, Mapping
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from dataclasses import dataclass
from typing import TypeVar

from heliostep.run.speed_torque import SpeedTorqueCurve, speed_torque_curve
from heliostep.scenario.catalogue import MotorDrive

__all__ = ["CurveTask", "on_every_core"]

K = TypeVar("K", bound=Hashable)
V = TypeVar("V")


@dataclass(frozen=True)
class CurveTask:
    """One speed-torque curve to co-simulate: the drive, its current [A], the step rates [full steps/s] and
    the sequencer's mode and microsteps."""

    drive: MotorDrive
    current: float
    rates: tuple[float, ...]
    mode: str
    microsteps: int

    def __call__(self) -> SpeedTorqueCurve:
        return speed_torque_curve(self.drive, self.current, self.rates, mode=self.mode, microsteps=self.microsteps)


def on_every_core(
    tasks: Mapping[K, Callable[[], V]],
    should_stop: Callable[[], bool] | None = None,
    workers: int | None = None,
    on_done: Callable[[K, V], None] | None = None,
) -> tuple[dict[K, V], bool]:
    """Each task's value by its key, on ``workers`` processes (default: one a core, at most one a task; one:
    here, one after another), ``on_done(key, value)`` as each finishes; and whether ``should_stop`` stopped
    them: it is asked before each task begins, so a stop leaves at most the tasks under way to finish (kept)."""
    workers = min(len(tasks), workers or os.cpu_count() or 1)
    done: dict[K, V] = {}
    queue = iter(tasks.items())

    def take(key: K, value: V) -> None:
        done[key] = value
        if on_done is not None:
            on_done(key, value)

    if workers <= 1:
        for key, task in queue:
            if should_stop is not None and should_stop():
                return done, True
            take(key, task())
        return done, False
    context = multiprocessing.get_context("forkserver")
    context.set_forkserver_preload([CurveTask.__module__])  # imported once by the server, not by every child
    stopped = False
    with ProcessPoolExecutor(workers, mp_context=context, initializer=_ignore_interrupts) as pool:
        running: dict[Future, K] = {}
        while True:
            while not stopped and len(running) < workers:
                item = next(queue, None)
                stopped = item is not None and should_stop is not None and should_stop()
                if item is None or stopped:
                    break
                running[pool.submit(item[1])] = item[0]
            if not running:
                return done, stopped
            finished, _ = wait(running, return_when=FIRST_COMPLETED)
            for future in finished:
                take(running.pop(future), future.result())


def _ignore_interrupts() -> None:
    """A pool child leaves SIGINT to the parent (a terminal's Ctrl+C reaches the whole process group)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
