"""The candidates' speed-torque curves for the sizing sheet, co-simulated on every core.

Each curve is a set of independent bench simulations (:func:`heliostep.run.speed_torque.speed_torque_curve`),
so the curves of a sheet (each candidate's, nominal and at the ranges' worst corner) go to a pool of processes
started by the standard library's fork server, one curve a task; a curve is the same whichever process
computes it. The children ignore SIGINT: a stop request is the parent's, which cancels the curves not begun
and waits for those under way.
"""

from __future__ import annotations

import multiprocessing
import os
import signal
from collections.abc import Callable, Mapping
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from dataclasses import dataclass

from heliostep.run.speed_torque import SpeedTorqueCurve, speed_torque_curve
from heliostep.scenario.catalogue import MotorDrive

__all__ = ["CurveTask", "co_simulated_curves"]


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


def co_simulated_curves(
    tasks: Mapping[str, CurveTask], should_stop: Callable[[], bool] | None = None, workers: int | None = None
) -> dict[str, SpeedTorqueCurve] | None:
    """Each task's curve by its key, on ``workers`` processes (default: one a core, at most one a task; one:
    here, one after another). None when ``should_stop`` says so before every curve is done."""
    workers = min(len(tasks), workers or os.cpu_count() or 1)
    if workers <= 1:
        curves = {}
        for key, task in tasks.items():
            if should_stop is not None and should_stop():
                return None
            curves[key] = task()
        return curves
    context = multiprocessing.get_context("forkserver")
    with ProcessPoolExecutor(workers, mp_context=context, initializer=_ignore_interrupts) as pool:
        futures: dict[Future, str] = {pool.submit(task): key for key, task in tasks.items()}
        curves, pending = {}, set(futures)
        while pending:
            done, pending = wait(pending, timeout=0.5, return_when=FIRST_COMPLETED)
            for future in done:
                curves[futures[future]] = future.result()
            if pending and should_stop is not None and should_stop():
                for future in pending:
                    future.cancel()
                return None
    return curves


def _ignore_interrupts() -> None:
    """A pool child leaves SIGINT to the parent (a terminal's Ctrl+C reaches the whole process group)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
