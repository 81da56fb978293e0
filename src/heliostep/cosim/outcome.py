"""How a run of the master ends: its result, its failure and its statistics."""

from __future__ import annotations

import time as clock
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pandas as pd

from heliostep.cosim.events import Terminated
from heliostep.errors import HeliostepError, InputError, RunFailure

__all__ = ["Interrupted", "MasterResult", "SimulationError", "completed", "ended", "statistics"]


class SimulationError(RunFailure):
    """The simulation failed or was stopped part-way; ``trace`` holds what was computed until then.

    ``reason`` is ``"failed"`` or ``"interrupted"`` (``should_stop`` asked to stop); ``time`` is
    the simulation time reached [s].
    """

    def __init__(
        self, message: str, trace: pd.DataFrame, statistics: dict, reason: str = "failed", time: float = float("nan")
    ):
        super().__init__(message)
        self.trace = trace
        self.statistics = statistics
        self.reason = reason
        self.time = time


class Interrupted(Exception):
    """Raised inside the main loop when ``should_stop`` says so (between solver calls)."""


@dataclass
class MasterResult:
    """A finished co-simulation: the trace and the solver statistics.

    ``terminated`` is True when an FMU asked to stop (terminateSimulation) before the stop
    time: the run then ended normally at ``termination_time`` for ``termination_reason``.
    """

    trace: pd.DataFrame
    statistics: dict = field(default_factory=dict)
    terminated: bool = False
    termination_reason: str = ""
    termination_time: float | None = None


def completed(run: Any, start_time: float, stop_time: float, grid: np.ndarray) -> MasterResult:
    """``run`` (the master's ``_Run``) executed from ``start_time`` to ``stop_time`` [s] with output rows at
    ``grid``, its FMUs freed on every path: the result, or a :class:`SimulationError` carrying the rows so
    far (an :class:`~heliostep.errors.InputError` before any row raised as it is)."""
    try:
        run.execute(start_time, stop_time, grid)
    except Interrupted:
        raise SimulationError(
            f"interrupted at t = {run.time:.9g} s",
            run.rows.trace(),
            statistics(run),
            reason="interrupted",
            time=run.time,
        ) from None
    except InputError as exc:
        if not run.rows.total:  # found setting up the FMUs: bad input, not a failed simulation
            raise
        raise failure(run, exc) from exc
    except (HeliostepError, RuntimeError) as exc:
        raise failure(run, exc) from exc
    finally:
        run.close()
    return MasterResult(
        run.rows.trace(),
        statistics(run),
        terminated=run.terminated,
        termination_reason=run.termination_reason,
        termination_time=run.termination_time,
    )


def ended(run: Any, stop: Terminated) -> None:
    """``run`` ended normally at ``stop.time`` [s]: an FMU asked to terminate the simulation."""
    run.terminated, run.termination_reason, run.termination_time = True, stop.reason, stop.time
    run.termination_instances = list(stop.instances)


def failure(run: Any, exc: BaseException) -> SimulationError:
    """The SimulationError of a run that failed with ``exc`` at the time reached."""
    return SimulationError(
        f"simulation failed at t = {run.time:.9g} s: {exc}", run.rows.trace(), statistics(run), time=run.time
    )


def statistics(run: Any) -> dict:
    """The run's counters and what it met (terminations, loops, sampled components, text outputs)."""
    system, integrator = run.system, run.integrator
    rhs = (system.rhs_evaluations if system is not None else 0) + (
        integrator.rhs_evaluations() if integrator is not None else 0
    )
    counts = {"rhs": rhs, **run.counts, "nominal_reads": system.nominal_reads if system is not None else 0}
    return {
        **counts,
        "compiled_rhs": integrator is not None and integrator.compiled,
        "wall_time": clock.perf_counter() - run.wall_start,
        "states": system.n_states if system is not None else 0,
        "event_indicators": system.n_indicators if system is not None else 0,
        "terminated": run.terminated,
        "termination_reason": run.termination_reason,
        "termination_time": run.termination_time,
        "termination_instances": run.termination_instances,
        "algebraic_loops": list(run.graph.loops),
        **({"sampled_components": run.graph.sampled.statistics()} if run.graph.sampled is not None else {}),
        "max_buffered_rows": run.rows.max_buffered,
        **({"text_outputs": run.texts.values} if run.texts is not None else {}),
        **(system.loop.statistics() if system is not None and system.loop is not None else {}),
    }
