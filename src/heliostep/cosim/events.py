"""Event mode of the coupled system: the discrete fixed point and ``terminateSimulation``.

Every FMU enters event mode, the master's new inputs are set, the event update iterates to a fixed
point with the outputs re-propagated between rounds, and every FMU returns to continuous-time mode;
an FMU asking to terminate raises :class:`Terminated`, which ends the run normally at that instant.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from heliostep.cosim.system import CoupledSystem
from heliostep.errors import RunFailure

__all__ = ["Resume", "Terminated", "discrete_fixed_point", "event_iteration"]


class Terminated(Exception):
    """An FMU asked to terminate the simulation (fmi2NewDiscreteStates/CompletedIntegratorStep)."""

    def __init__(self, reason: str, time: float, instances: Sequence[str] = ()):
        super().__init__(reason)
        self.reason = reason
        self.time = time
        self.instances = tuple(instances)  # the instances that asked


@dataclass
class Resume:
    """Where the compiled kernel (:mod:`heliostep.cosim.fast_events`) left a first iteration of
    ``fmi2NewDiscreteStates`` for the Python path to go on from: the outputs the round propagated from,
    and ``unit``, the index of the unit whose first call's answer ``info`` (an fmi2EventInfo) asks for more
    (its iteration goes on from it, then the units after it); ``unit`` None: the round is complete and
    changed the outputs to ``previous`` (the next iteration follows). The units before ``unit`` answered
    with no flag set."""

    previous: np.ndarray
    unit: int | None = None
    info: Any = None


def discrete_fixed_point(
    system: CoupledSystem, time: float, max_rounds: int = 100, resume: Resume | None = None
) -> bool:
    """NewDiscreteStates on every FMU, re-propagating outputs, until nothing changes; whether a
    discrete state changed. ``time`` [s] is the run's time, for the messages; ``resume``: go on from
    a first iteration the compiled kernel began (:class:`Resume`).

    The outputs are compared with those the round propagated from (read before the first
    round): when NewDiscreteStates changed none, the inputs set from them are consistent
    and one round is the fixed point (a step instant of the shipped drive needs one)."""
    changed = False
    previous = system.outputs() if resume is None else resume.previous
    rounds = range(max_rounds) if resume is None or resume.unit is not None else range(1, max_rounds)
    for round_ in rounds:
        start, first = 0, None
        if resume is not None and resume.unit is not None and round_ == 0:
            start, first = resume.unit, resume.info  # the kernel propagated and called the units before
        else:
            system.propagate_at_event()
        stop = []
        for unit in system.unit_list[start:]:
            if first is not None:
                result, first = unit.fmu.update_discrete_states(first=first), None  # an FMI 2.0 unit
            else:
                result = unit.fmu.update_discrete_states()
            changed |= result.states_changed
            system.nominals_changed |= result.nominals_changed
            unit.next_event_time = result.next_event_time
            if result.terminate:
                stop.append(unit.name)
        if stop:  # the round is complete: pass the final outputs on, then end the run
            system.propagate_at_event()
            functions = sorted({unit.info.kind.update_function for unit in system.unit_list if unit.name in stop})
            raise Terminated(
                f"{', '.join(stop)} asked to terminate the simulation ({'/'.join(functions)}: terminateSimulation)",
                time,
                stop,
            )
        outputs = system.outputs()
        if np.array_equal(outputs, previous):
            return changed
        previous = outputs
    raise RunFailure(f"event iteration at t = {time} found no fixed point in {max_rounds} rounds")


def event_iteration(
    system: CoupledSystem, input_values: np.ndarray, new_values: Sequence[float] | None, time: float
) -> None:
    """Event mode: every FMU enters it; with ``new_values`` the master's inputs change to them
    (written into ``input_values`` in place: the compiled kernel reads that array) and are set;
    then the discrete fixed point, and every FMU back to continuous-time mode."""
    for unit in system.unit_list:
        unit.fmu.enter_event_mode()
    if new_values is not None:
        input_values[:] = new_values
        system.apply_inputs()
    discrete_fixed_point(system, time)
    for unit in system.unit_list:
        unit.fmu.enter_continuous_time_mode()
