"""Co-Simulation FMUs (FMI 2.0 and 3.0) as sampled components of the Model Exchange system.

A sampled component steps (``DoStep``) at a fixed communication interval (the scenario's
``communication_interval.NAME``); its inputs are sampled at each communication point and held, its
outputs held between points (loose coupling: a delay of up to one interval). Each communication point
is a time event of the Model Exchange system, and the component's outputs are master inputs of it
(:class:`SampledSignal`), so the compiled kernel stays in use (a system of them alone runs its points in a
loop of its own: :mod:`~heliostep.cosim.communication`). An algebraic loop through a component is
refused up front (:func:`split_sampled`), unless it is made of components only (each steps with the others'
outputs of the point before: nothing to solve); only Real (FMI 3.0: Float64) variables connect, a connection into a
component with its transformation applied to the value sampled (``factor * value + offset``). A step whose
FMU asks to terminate ends the run at that point (:class:`~heliostep.cosim.events.Terminated`).
"""

from __future__ import annotations

import bisect
import ctypes
import functools
import math
import re
from collections.abc import Callable, Mapping, Sequence
from typing import TYPE_CHECKING

import numpy as np

from heliostep.cosim.co_simulation import CoSimulationInstanceBase
from heliostep.cosim.connections import ConnectionGraph, split_name
from heliostep.cosim.description import FMUInfo
from heliostep.cosim.events import Terminated
from heliostep.cosim.fmi import _callbacks
from heliostep.cosim.instance import VALUES_CALL, FMIError
from heliostep.cosim.signals import Connection, PiecewiseConstant
from heliostep.errors import InputError

if TYPE_CHECKING:
    from heliostep.cosim.system import CoupledSystem

#: fmi2Status fmi2Warning, fmi2Discard and fmi2StatusKind fmi2LastSuccessfulTime, fmi2Terminated (fmi2FunctionTypes.h)
FMI2_WARNING, FMI2_DISCARD, FMI2_LAST_SUCCESSFUL_TIME, FMI2_TERMINATED = 1, 2, 2, 3
#: fmi2DoStep(c, currentCommunicationPoint, communicationStepSize, noSetFMUStatePriorToCurrentPoint)
_DO_STEP = ctypes.CFUNCTYPE(ctypes.c_int, ctypes.c_void_p, ctypes.c_double, ctypes.c_double, ctypes.c_int)

__all__ = ["CoSimulationInstance", "SampledComponent", "SampledSignal", "SampledSystem", "split_sampled"]


class CoSimulationInstance(CoSimulationInstanceBase):
    """One instance of an FMI 2.0 Co-Simulation FMU (fmpy's ``FMU2Slave``), every FMI error an
    :class:`~heliostep.cosim.fmi.FMIError` naming the instance, the function, the time and the FMU's messages.
    The calls of every communication point (``fmi2DoStep``, ``fmi2GetReal``, ``fmi2SetReal``) are bound with
    heliostep's own prototypes on buffers kept per caller (fmpy's per-call wrapper costs more than the call)."""

    _FMI, _REAL = "fmi2", "Real"
    TERMINATION = "fmi2DoStep: fmi2Discard, then fmi2Terminated"

    def __init__(self, info: FMUInfo, name: str, parameters: Mapping[str, object]):
        from fmpy.fmi2 import FMU2Slave

        super().__init__(info, name, parameters)
        self._callbacks = _callbacks(self._environment)
        slave = self._new_slave(FMU2Slave)
        self._do("fmi2Instantiate", slave.instantiate, callbacks=self._callbacks)
        self._slave = slave
        self._step = functools.partial(_DO_STEP(("fmi2DoStep", slave.dll)), slave.component)
        self._buffers: list[ctypes.Array | np.ndarray] = []  # what the bound calls point to

    def _failure(self, function: str, status: int) -> FMIError:
        """The error of an FMI call that returned ``status`` (worse than fmi2Warning), worded as fmpy words it."""
        from fmpy.fmi1 import FMICallException

        said = FMICallException(function, status)
        return FMIError(function, self.name, f"failure ({said})", self.messages, self.time)

    def _values_call(self, function: str, names: Sequence[str], values: np.ndarray) -> Callable[[], None]:
        """``function`` (fmi2GetReal, fmi2SetReal) bound to the value references of ``names`` and to ``values``
        (a C-contiguous float64 vector, kept alive here), its failure an FMIError."""
        refs = (ctypes.c_uint32 * len(names))(*(self.info.variables[n].value_reference for n in names))
        call = VALUES_CALL((function, self._slave.dll))
        bound = functools.partial(call, self._slave.component, ctypes.addressof(refs), len(names), values.ctypes.data)
        self._buffers += [refs, values]
        messages = self.messages

        def checked() -> None:
            messages.clear()
            status = bound()
            if status > FMI2_WARNING:
                raise self._failure(function, status)

        return checked

    def real_getter(self, names: Sequence[str], values: np.ndarray) -> Callable[[], None]:
        return self._values_call("fmi2GetReal", names, values)

    def real_setter(self, names: Sequence[str], values: np.ndarray) -> Callable[[], None]:
        return self._values_call("fmi2SetReal", names, values)

    def real_reader(self, names: Sequence[str]) -> Callable[[], list[float]]:
        values = np.zeros(len(names))
        get = self.real_getter(names, values)

        def read() -> list[float]:
            get()
            return values.tolist()

        return read

    def real_writer(self, names: Sequence[str]) -> Callable[[Sequence[float]], None]:
        values = np.zeros(len(names))
        put = self.real_setter(names, values)

        def write(given: Sequence[float]) -> None:
            values[:] = given
            put()

        return write

    def _enter_initialization_mode(self, start_time: float, stop_time: float) -> None:
        """fmi2SetupExperiment (start and stop time [s]) and fmi2EnterInitializationMode."""
        self._do("fmi2SetupExperiment", self._slave.setupExperiment, startTime=start_time, stopTime=stop_time)
        self._do("fmi2EnterInitializationMode", self._slave.enterInitializationMode)

    def _setter(self, name: str) -> str:
        setter = {"Real": "setReal", "Integer": "setInteger", "Enumeration": "setInteger", "Boolean": "setBoolean"}
        return setter.get(self.info.variables[name].type, "setString")

    def do_step(self, to_time: float) -> bool:
        """fmi2DoStep from the instance's time to ``to_time`` [s]; whether the FMU asks to terminate.

        FMI 2.0 has no termination flag on a step: a slave that must stop returns ``fmi2Discard``
        and then says ``fmi2Terminated`` through ``fmi2GetBooleanStatus`` (FMI 2.0.4, section 4.2.3:
        the master may then read its outputs and must not step it again). heliostep takes that as
        the FMU asking to terminate at this communication point (the run ends there, as for an FMI
        3.0 ``terminateSimulation``); the last time the slave reached (``fmi2LastSuccessfulTime``)
        is kept in :attr:`last_successful_time` where the FMU tells it. A discarded step without
        ``fmi2Terminated`` is an :class:`~heliostep.cosim.fmi.FMIError`: a sampled component's
        communication points are fixed, so heliostep does not retry with a shorter step.
        """
        self.messages.clear()
        status = self._step(self.time, to_time - self.time, True)
        if status > FMI2_WARNING:
            if status != FMI2_DISCARD:
                raise self._failure("fmi2DoStep", status)
            if not self._discarded_because_terminated(to_time):
                detail = (
                    f"fmi2Discard without fmi2Terminated (the step from t = {self.time:g} s to {to_time:g} s; a "
                    "sampled component's communication points are fixed: heliostep does not retry a shorter step)"
                )
                raise FMIError("fmi2DoStep", self.name, detail, self.messages, self.time) from None
            self.time = to_time
            return True
        self.time = to_time
        return False

    def _discarded_because_terminated(self, to_time: float) -> bool:
        """After an ``fmi2Discard``: whether the slave says ``fmi2Terminated`` (a status it cannot
        give counts as no), with its ``fmi2LastSuccessfulTime`` [s] kept where it gives one."""
        try:
            terminated = bool(self._slave.getBooleanStatus(FMI2_TERMINATED))
        except Exception:  # noqa: BLE001 - fmi2GetBooleanStatus unsupported: not a termination
            return False
        try:
            self.last_successful_time = float(self._slave.getRealStatus(FMI2_LAST_SUCCESSFUL_TIME))
        except Exception:  # noqa: BLE001 - optional for the slave: the point asked for stands
            self.last_successful_time = to_time
        return terminated


class SampledComponent:
    """A Co-Simulation FMU stepped every ``interval`` [s]: its held outputs and its communication points."""

    def __init__(self, name: str, info: FMUInfo, interval: float, parameters: Mapping[str, object]):
        self.name, self.info, self.interval = name, info, float(interval)
        self.parameters = dict(parameters)
        self.outputs = [v for v in info.outputs if info.variables[v].type == "Real"]
        self.held = {v: float(info.variables[v].start or 0.0) for v in self.outputs}  # before the start: starts
        self.current = {v: np.array([value]) for v, value in self.held.items()}  # the same, as arrays kept
        self.times: np.ndarray = np.zeros(0)  # the communication points after the start, up to the stop time
        self.steps = 0
        self.instance: CoSimulationInstanceBase | None = None
        self._points: list[float] = []  # the times as floats; the next one not stepped to at _next
        self._next = 0
        self._outputs: Callable[[], list[float]] = list

    def start(self, start_time: float, stop_time: float, inputs: Mapping[str, float]) -> None:
        count = math.floor((stop_time - start_time) / self.interval * (1.0 + 1e-12))
        self.times = np.minimum(start_time + self.interval * np.arange(1, count + 1), stop_time)  # k h rounded past it
        if not len(self.times) or self.times[-1] < stop_time * (1.0 - 1e-12):
            self._check_shorter_step(stop_time - start_time)
            self.times = np.append(self.times, stop_time)  # the last point at the stop time
        self.steps = 0
        self._points, self._next = self.times.tolist(), 0
        self.instance = self.info.kind.instance_class()(self.info, self.name, self.parameters)
        self.instance.initialize(start_time, stop_time, inputs)
        if self.outputs:
            self._outputs = self.instance.real_reader(self.outputs)
        self._read()

    def _check_shorter_step(self, window: float) -> None:
        """A last step shorter than the interval needs ``canHandleVariableCommunicationStepSize``
        (FMI 2.0 and 3.0: false unless the FMU says true); InputError naming the key otherwise."""
        interface = getattr(self.info.description, "coSimulation", None)
        if interface is not None and not getattr(interface, "canHandleVariableCommunicationStepSize", False):
            raise InputError(
                f"communication_interval.{self.name}: {self.interval:g} s does not divide the window ({window:g} s), "
                f"and {self.info.path.name} cannot take a shorter last step (its CoSimulation element has no "
                'canHandleVariableCommunicationStepSize="true"): choose an interval that divides the window'
            )

    def _read(self) -> None:
        if self.outputs:
            self.held = dict(zip(self.outputs, self._outputs()))
            for variable, value in self.held.items():
                self.current[variable][0] = value

    def due(self, time: float) -> bool:
        """Whether ``time`` [s] is a communication point this component has not stepped to yet: a point
        within 1e-9 relative of it (the next one first, else found by bisection: the points are sorted)."""
        assert self.instance is not None
        scale = max(1.0, abs(time))
        if not time > self.instance.time + 1e-12 * scale:
            return False
        points, tolerance = self._points, 1e-9 * scale
        if self._next < len(points) and abs(points[self._next] - time) <= tolerance:
            return True
        k = bisect.bisect_left(points, time - tolerance)
        return any(abs(points[j] - time) <= tolerance for j in (k - 1, k) if 0 <= j < len(points))

    def step(self, time: float) -> bool:
        """Step to ``time`` [s] (the outputs not read); whether the FMU asks to terminate the simulation."""
        assert self.instance is not None
        terminate = self.instance.do_step(time)
        self.steps += 1
        self._next = bisect.bisect_right(self._points, time, lo=self._next)
        return terminate

    def step_to(self, time: float) -> bool:
        """Step to ``time`` [s] and read the outputs; whether the FMU asks to terminate the simulation."""
        terminate = self.step(time)
        self._read()
        return terminate


class SampledSignal:
    """A sampled component's output as a master input of the Model Exchange system (duck-typed like
    :class:`~heliostep.cosim.signals.PiecewiseConstant`): it changes at the component's communication
    points, to the value the component's step gives (asked of ``group`` when the master asks).

    As a piecewise-constant signal it has no change time of its own (the master stops at the
    component's points, :attr:`SampledComponent.times`) and one value, the one held now: the array
    the component updates in place at each step, which the compiled kernel reads at an event."""

    def __init__(self, group: SampledSystem, component: SampledComponent, variable: str, target: str):
        self.group, self.component, self.variable = group, component, variable
        self.name = f"{component.name}.{variable}"
        self.target = target
        self.times = np.zeros(0)
        self.values = component.current[variable]

    def value_at(self, time: float) -> float:
        stop = self.group.communicate(time)  # the master communicates first: nothing due here, normally
        if stop is not None:
            raise stop
        return self.component.held[self.variable]


class SampledSystem:
    """The sampled components of a run and their connections to the Model Exchange system."""

    def __init__(self, components: dict[str, SampledComponent], connections: Sequence[Connection]):
        self.components = components
        self.connections = list(connections)  # every connection with a sampled end
        self.signals: list[SampledSignal] = []  # every Real output traced; each drives its Model Exchange inputs
        for name, component in components.items():
            for output in component.outputs:
                targets = [
                    c.target
                    for c in self.connections
                    if c.source == f"{name}.{output}" and split_name(c.target, "target")[0] not in components
                ]
                for k, target in enumerate(targets or [""]):
                    signal = SampledSignal(self, component, output, target)
                    if k:  # the same value driving a second input: a column of its own name
                        signal.name = f"{signal.name} -> {target}"
                    self.signals.append(signal)
        self._inputs: dict[str, tuple[list[Callable[[], float]], Callable[[Sequence[float]], None]]] = {}
        self._communicated = math.nan  # the time of the last communication (asked again there: nothing due)

    def start(self, start_time: float, stop_time: float) -> None:
        """Every component instantiated and initialized (its inputs at their start values)."""
        for component in self.components.values():
            starts = {
                split_name(c.target, "target")[1]: float(
                    component.info.variables[split_name(c.target, "t")[1]].start or 0.0
                )
                for c in self.connections
                if split_name(c.target, "target")[0] == component.name
            }
            component.start(start_time, stop_time, starts)

    def bind(self, system: CoupledSystem) -> None:
        """The readers of each sampled component's inputs: Model Exchange outputs of ``system``, or
        another component's held output; then every input sampled (the start)."""
        readers: dict[str, list[tuple[str, Callable[[], float]]]] = {}
        for c in self.connections:
            target, variable = split_name(c.target, "target")
            if target not in self.components:
                continue
            source, output = split_name(c.source, "source")
            if source in self.components:
                read: Callable[[], float] = functools.partial(_held_value, self.components[source], output)
            else:
                read = functools.partial(_first_value, system.units[source].fmu.reader([output]))
            if c.transform is not None and c.transform != (1.0, 0.0):
                read = functools.partial(_transformed, *c.transform, read)
            readers.setdefault(target, []).append((variable, read))
        self._inputs = {}
        for name, pairs in readers.items():
            instance = self.components[name].instance
            if instance is not None:
                self._inputs[name] = ([p[1] for p in pairs], instance.real_writer([p[0] for p in pairs]))
        self._sample(list(self.components.values()))

    def _sample(self, components: list[SampledComponent]) -> None:
        for component in components:
            inputs = self._inputs.get(component.name)
            if inputs is not None:
                reads, write = inputs
                write([read() for read in reads])

    def communicate(self, time: float) -> Terminated | None:
        """At a communication point: the components due step to it with the inputs they held, then
        their inputs are sampled (the Model Exchange system at ``time``, before its event). A
        :class:`~heliostep.cosim.events.Terminated` to raise once the event is handled (the held outputs
        passed on) when a component asked to terminate the simulation, else None. Asked again at the
        same time (each signal's value asks), nothing is due: answered at once."""
        if time == self._communicated:
            return None
        self._communicated = time
        due = [component for component in self.components.values() if component.due(time)]
        stop = [component.name for component in due if component.step_to(time)]
        self._sample(due)
        return self.terminated(stop, time) if stop else None

    def terminated(self, names: Sequence[str], time: float) -> Terminated:
        """What ends the run at ``time`` [s] when the components ``names`` asked to terminate at that point."""
        said = []
        for name in names:
            instance = self.components[name].instance
            assert instance is not None
            reached = instance.last_successful_time
            at = f", its last successful time {reached:.9g} s" if reached is not None and reached != time else ""
            said.append(f"{name} asked to terminate the simulation ({instance.TERMINATION}{at})")
        return Terminated("; ".join(said), time, list(names))

    def statistics(self) -> dict[str, dict[str, float]]:
        return {name: {"interval_s": c.interval, "steps": c.steps} for name, c in self.components.items()}

    def close(self) -> None:
        for component in self.components.values():
            if component.instance is not None:
                component.instance.close()


def _held_value(component: SampledComponent, output: str) -> float:
    return component.held[output]


def _first_value(reader: Callable[[], np.ndarray]) -> float:
    return float(reader()[0])


def _transformed(factor: float, offset: float, read: Callable[[], float]) -> float:
    """The value ``read`` gives, transformed as the connection says (the product rounded before the sum)."""
    return factor * read() + offset


def split_sampled(
    fmus: Mapping[str, FMUInfo],
    connections: Sequence[Connection],
    inputs: Sequence[PiecewiseConstant],
    intervals: Mapping[str, float],
    parameters: Mapping[str, Mapping[str, object]] | None = None,
) -> tuple[dict[str, FMUInfo], list[Connection], SampledSystem | None]:
    """The Model Exchange FMUs and connections, and the sampled system of the Co-Simulation FMUs
    (None without any); InputError for what a sampled component cannot do: an instance read for
    Co-Simulation without an interval (or the reverse), a master input driving it, a non-Real connection, a
    transformed one from it into a Model Exchange FMU, an algebraic loop through it and a Model Exchange FMU
    (named, with the loop)."""
    sampled = {name for name, info in fmus.items() if info.co_simulation}
    for name in sorted(sampled ^ set(intervals)):
        raise InputError(
            f"FMU instance {name!r}: communication_interval.{name} and its FMU read for Co-Simulation go together"
        )
    if not sampled:
        return dict(fmus), list(connections), None
    for item in inputs:
        if split_name(item.target, "input target")[0] in sampled:
            raise InputError(
                f"input {item.name} drives {item.target}, an input of a Co-Simulation FMU: master inputs drive"
                " Model Exchange FMUs only"
            )
    graph = ConnectionGraph(fmus, connections)  # every end checked (units, types); loops found over all FMUs
    for loop in graph.loops:
        named = {name for name in fmus if re.search(rf"(?<![\w.]){re.escape(name)}\.", loop)}
        inside = sorted(named & sampled)
        if inside and named - sampled:  # (a loop of sampled components only: each steps with the held values)
            raise InputError(
                f"the Co-Simulation FMU {inside[0]!r} ({fmus[inside[0]].path.name}) is in an algebraic loop: {loop}; "
                "a sampled component's outputs are held between communication points, so the loop cannot be solved "
                "there: break it with a state, remove a connection, or use the FMU as Model Exchange"
            )
    ends = [c for c in connections if {split_name(c.source, "s")[0], split_name(c.target, "t")[0]} & sampled]
    for c in ends:
        if c.transform is not None and split_name(c.target, "target")[0] not in sampled:
            raise InputError(
                f"connection {c.source} -> {c.target}: a transformation on a connection from a Co-Simulation FMU"
                " into a Model Exchange FMU is not supported (use the source as Model Exchange, or move the"
                " transformation into the FMU)"
            )
        for end in (c.source, c.target):
            instance, variable = split_name(end, "connection end")
            if instance in sampled and fmus[instance].variables[variable].type != "Real":
                raise InputError(
                    f"connection {c.source} -> {c.target}: only Real variables of a Co-Simulation FMU connect"
                )
    values = parameters or {}
    ordered = [name for name in fmus if name in sampled]  # in the order of the instances (the trace's columns)
    components = {name: SampledComponent(name, fmus[name], intervals[name], values.get(name, {})) for name in ordered}
    me_fmus = {name: info for name, info in fmus.items() if name not in sampled}
    return me_fmus, [c for c in connections if c not in ends], SampledSystem(components, ends)
