"""The co-simulation master: Model Exchange FMUs solved as one system on one CVODE.

The run's call order: instantiate every FMU (sampled Co-Simulation components first), set the master
inputs, propagate the connections, exit initialization mode, iterate the discrete states to a fixed
point and enter continuous-time mode; then, until the stop time, integrate to the next input change,
FMU time event or stop time (output rows interpolated between CVODE's internal steps when a monitor
watches), call ``CompletedIntegratorStep`` where the FMU asks for it, and at an input change, time,
state or step event record the row before, run event mode (:mod:`~heliostep.cosim.events`, or
:mod:`~heliostep.cosim.fast_events` in one call of the kernel), restart CVODE and record the row after.
An FMU's ``terminateSimulation`` ends the run normally there; every instance is terminated (where
allowed) and freed on every path (:mod:`~heliostep.cosim.outcome`). A system of Co-Simulation FMUs alone
has nothing to integrate: its run is its communication points (:mod:`~heliostep.cosim.communication`).
"""

from __future__ import annotations

import time as clock
from collections.abc import Callable, Mapping, Sequence
from typing import Protocol

import numpy as np

from heliostep.cosim import fast_events as events
from heliostep.cosim.communication import CommunicationLoop
from heliostep.cosim.connections import ConnectionGraph
from heliostep.cosim.controller import ControllerSamples, SampledController
from heliostep.cosim.events import Terminated, discrete_fixed_point, event_iteration
from heliostep.cosim.fmi import FMUInfo, convert_value
from heliostep.cosim.integrator import Integrator, make_integrator
from heliostep.cosim.outcome import Interrupted, MasterResult, SimulationError, completed, ended
from heliostep.cosim.rows import RowBuffer
from heliostep.cosim.sampled import split_sampled
from heliostep.cosim.signals import Connection, PiecewiseConstant, SolverOptions
from heliostep.cosim.system import CoupledSystem
from heliostep.cosim.text_outputs import TextOutputs
from heliostep.errors import InputError

__all__ = [
    "CoSimulation",
    "Connection",
    "MasterResult",
    "PiecewiseConstant",
    "SimulationError",
    "SolutionMonitor",
    "SolverOptions",
]


class SolutionMonitor(Protocol):
    """What the master calls on its ``monitor``: every solution row it records, in blocks."""

    def __call__(self, rows: np.ndarray) -> None:
        """Take ``rows``: a 2-D block laid out like the trace's rows (time, master inputs, FMU outputs),
        in time order, holding every internal solver step, both sides of every event and every
        output time; valid during the call only."""
        ...


class CoSimulation(ConnectionGraph):
    """Connected Model Exchange FMUs and the inputs the master drives, simulated as one system.

    Parameters
    ----------
    fmus : mapping of str to FMUInfo
        FMU instances by name (read with :func:`heliostep.cosim.fmi.read_fmu`).
    connections : sequence of Connection
        FMU outputs to FMU inputs. Connected variables must have the same unit.
    inputs : sequence of PiecewiseConstant
        Master-side inputs and the FMU inputs they drive.
    parameters : mapping of str to mapping of str to float, optional
        Parameter values per instance.
    controller : SampledController, optional
        Sampled while simulating: it reads FMU outputs and appends changes to the inputs it drives
        (:mod:`heliostep.cosim.controller`).
    """

    def __init__(
        self,
        fmus: Mapping[str, FMUInfo],
        connections: Sequence[Connection] = (),
        inputs: Sequence[PiecewiseConstant] = (),
        parameters: Mapping[str, Mapping[str, float]] | None = None,
        communication_intervals: Mapping[str, float] | None = None,
        controller: SampledController | None = None,
    ):
        parameters = parameters or {}
        self.controller = controller
        unknown = set(parameters) - set(fmus)
        if unknown:
            raise InputError(
                f"parameters given for unknown FMU instance(s) {sorted(unknown)}; instances: {', '.join(fmus)}"
            )
        fmus, connections, self.sampled = split_sampled(
            fmus, connections, inputs, communication_intervals or {}, parameters
        )  # Co-Simulation FMUs: sampled components, their outputs master inputs of the Model Exchange system
        parameters = {name: values for name, values in parameters.items() if name in fmus}
        signals = self.sampled.signals if self.sampled is not None else []
        scheduled = list(controller.inputs) if controller is not None else []
        super().__init__(fmus, connections, [*inputs, *signals, *scheduled])  # type: ignore[list-item]
        if controller is not None:
            _check_controller(self, controller)
        self.parameters = {name: dict(parameters.get(name, {})) for name in fmus}
        for name, values in self.parameters.items():  # every value must fit its type, up front
            info = self.fmus[name]
            for parameter, value in values.items():
                if parameter in info.variables and info.variables[parameter].causality == "parameter":
                    convert_value(info.variables[parameter], value)

    # ------------------------------------------------------------------ simulation
    def simulate(
        self,
        start_time: float,
        stop_time: float,
        output_times: np.ndarray | None = None,
        solver: SolverOptions | None = None,
        progress: Callable[[float], None] | None = None,
        monitor: SolutionMonitor | None = None,
        should_stop: Callable[[], bool] | None = None,
        sink: Callable[[np.ndarray], None] | None = None,
        sink_rows: int = 4096,
    ) -> MasterResult:
        """Integrate from ``start_time`` to ``stop_time`` [s].

        Returns the trace with a row at each of ``output_times`` (default: start and stop)
        and rows just before/after each event. On failure raises :class:`SimulationError`
        carrying the trace so far; an :class:`~heliostep.errors.InputError` found while setting
        up the FMUs (before any row) is raised as it is.

        ``monitor``, when given, is called with blocks of rows (2-D arrays laid out like the
        trace's rows: time, master inputs, FMU outputs; in time order; valid during the call only)
        holding a row at **every internal step of the solver**, at every event (both sides) and
        at every output time, so figures such as peaks and integrals can be
        computed from the solution itself rather than from the output grid (CVODE then runs in
        one-step mode up to each stop, the output rows interpolated). ``should_stop`` is asked
        between solver calls; when it returns True the run stops there with a
        :class:`SimulationError` whose ``reason`` is ``"interrupted"``.

        ``sink``, when given, receives the trace rows as they are produced, in time order, as 2-D
        blocks (rows × the trace's columns) of at most ``sink_rows`` rows; the master then holds
        at most ``sink_rows`` rows, or one larger block stored at once, which it passes straight on
        (``statistics["max_buffered_rows"]`` is the most it held), and the trace it returns
        (or carries in :class:`SimulationError`) has the columns but no rows. The last block is
        handed over before this returns or raises, also when the run fails or is interrupted.
        """
        if not stop_time > start_time:
            raise InputError(f"stop time {stop_time} must be after start time {start_time}")
        points = [start_time, stop_time] if output_times is None else output_times
        grid = np.unique(np.clip(np.asarray(points, dtype=float), start_time, stop_time))
        run = _Run(self, solver or SolverOptions(), progress, monitor, should_stop, sink, sink_rows)
        return completed(run, start_time, stop_time, grid)


class _Run:
    """One integration: the coupled system, its integrator, the events and the recorded rows."""

    def __init__(
        self,
        graph: CoSimulation,
        options: SolverOptions,
        progress: Callable[[float], None] | None,
        monitor: SolutionMonitor | None = None,
        should_stop: Callable[[], bool] | None = None,
        sink: Callable[[np.ndarray], None] | None = None,
        sink_rows: int = 4096,
    ):
        self.graph = graph
        self.options = options
        self.progress = progress
        self.monitor = monitor
        self.should_stop = should_stop
        columns = ["time"] + [item.name for item in graph.inputs]
        for name, info in graph.fmus.items():
            columns += [f"{name}.{output}" for output in info.traced_outputs]
        self.rows = RowBuffer(columns, sink, sink_rows)
        self.input_values = np.array([item.values[0] for item in graph.inputs], dtype=float)
        self.time = np.nan
        self.counts = {"integrator_calls": 0, "events": 0, "state_events": 0, "time_events": 0}
        self.counts.update(compiled_events=0, resumed_events=0)  # (fast_events) in the kernel, begun there
        self.wall_start = clock.perf_counter()
        self.terminated, self.termination_reason = False, ""
        self.termination_time: float | None = None
        self.termination_instances: list[str] = []
        self.system: CoupledSystem | None = None  # from the start of execute
        self.integrator: Integrator | None = None  # once the FMUs are initialized
        self.texts: TextOutputs | None = None  # the String and Binary outputs, if any
        self._no_outputs = np.zeros(0)
        self.fast_events: events.FastEvents | None = None  # the events in one call of the kernel, where allowed
        self.samples: ControllerSamples | None = None  # the controller's, from the start of execute

    # --------------------------------------------------------------- results
    def close(self) -> None:
        """fmi2Terminate (where allowed) and fmi2FreeInstance for every instance, on every path;
        CVODE's memory freed."""
        if self.graph.sampled is not None:
            self.graph.sampled.close()
        if self.system is not None:
            self.system.close()
        if self.integrator is not None:
            self.integrator.close()

    # --------------------------------------------------------------- recording
    def record(self, t: float) -> None:
        assert self.system is not None
        row = self.system.row(t)[None, :]
        self.rows.store(row)
        if self.monitor is not None:
            self.monitor(row)

    def _take_rows(self, rows: np.ndarray, kinds: np.ndarray) -> None:
        """Rows from the one-step loop: all to the monitor, the output rows (kind 1) to the
        trace; then ``should_stop`` is asked (on a stop, the last row ends the trace)."""
        if self.monitor is not None:
            self.monitor(rows)
        outputs = kinds == 1
        if outputs.any():
            self.rows.store(np.ascontiguousarray(rows[outputs]))
        self.time = float(rows[-1, 0])
        if self.should_stop is not None and self.should_stop():
            if kinds[-1] != 1:  # the trace ends where the run stops: at the last solution row
                self.rows.store(rows[-1:].copy())
            raise Interrupted()

    # --------------------------------------------------------------- events
    def _event_iteration(
        self, system: CoupledSystem, t: float, new_inputs: bool, input_time: float, stop: Terminated | None = None
    ) -> None:
        """Event mode at ``t``: set inputs (their values from ``input_time`` on), iterate discrete states
        to a fixed point (``stop``: what the sampled components said, where they stepped already)."""
        self.counts["events"] += 1
        if self.graph.sampled is not None:  # at a communication point the sampled components step
            stop = self.graph.sampled.communicate(t) or stop  # a CS FMU's terminateSimulation: after the new inputs
        new_values = [item.value_at(input_time) for item in self.graph.inputs] if new_inputs else None
        event_iteration(system, self.input_values, new_values, self.time)
        if self.texts is not None:
            self.texts.sample(t)
        if stop is not None:
            raise stop

    def _event(
        self, system: CoupledSystem, integrator: Integrator, t: float, new_inputs: bool, input_time: float | None = None
    ) -> None:
        """Record the row before, handle the event at ``t``, restart CVODE, record the row after. An input
        change within rounding after ``t`` is handled at ``t`` with its new values (``input_time``). The
        sampled components step first where the kernel takes the event (they change none of the row before)."""
        stop = _sampled_first(self, t) if self.fast_events is not None and self.graph.sampled is not None else None
        if self.fast_events is not None and stop is None:  # in one call of the kernel (Python after it where asked)
            return events.fast_event(self, t, new_inputs, t if input_time is None else max(t, input_time))
        self.record(t)
        self._event_iteration(system, t, new_inputs, t if input_time is None else max(t, input_time), stop)
        try:
            integrator.reset(t)  # re-reads the states (changed or not) and restarts CVODE
        except BaseException:
            self._raise_callback_error(integrator)
            raise
        self._raise_callback_error(integrator)
        self.record(t)

    def _raise_callback_error(self, integrator: Integrator) -> None:
        """Re-raise what a callback raised (a Python exception, or an FMI status the compiled
        kernel recorded), at the time of the failing evaluation."""
        taken = integrator.take_error()
        if taken is not None:
            error, self.time = taken
            raise error

    # --------------------------------------------------------------- set-up
    def _initialize(self, start_time: float, stop_time: float) -> CoupledSystem:
        """Instantiate and initialize the FMUs (inputs set, connections propagated, the first
        event iteration; the sampled components first, sampled last) and record the row at ``start_time``."""
        self.time = start_time
        sampled = self.graph.sampled
        if sampled is not None:  # their initial outputs are master inputs of the Model Exchange system
            sampled.start(start_time, stop_time)
            self.input_values[:] = [item.values[0] for item in self.graph.inputs]
        self.system = system = CoupledSystem(
            self.graph, self.graph.parameters, start_time, self.input_values, self.options
        )
        system.apply_inputs()
        system.propagate_at_event()
        for unit in system.unit_list:
            unit.fmu.exit_initialization_mode()
        discrete_fixed_point(system, self.time)
        texts = TextOutputs(system)
        self.texts = texts if texts.readers else None
        if self.texts is not None:
            self.texts.sample(start_time)
        for unit in system.unit_list:
            unit.fmu.enter_continuous_time_mode()
        if sampled is not None:
            sampled.bind(system)
        self.samples = ControllerSamples(self.graph.controller, system, start_time, stop_time)  # its sets given
        self.record(start_time)
        return system

    # --------------------------------------------------------------- main loop
    def execute(self, start_time: float, stop_time: float, grid: np.ndarray) -> None:
        """Run the integration (a system of Co-Simulation FMUs alone: its communication points,
        :mod:`~heliostep.cosim.communication`); an FMU's terminateSimulation ends it normally at that time."""
        sampled = self.graph.sampled
        if sampled is not None and not self.graph.fmus and self.graph.controller is None:
            CommunicationLoop(self, sampled).execute(start_time, stop_time, grid)
            return
        try:
            self._execute(start_time, stop_time, grid)
        except Terminated as stop:
            ended(self, stop)
            if self.texts is not None:
                self.texts.sample(stop.time)
            self.record(stop.time)

    def _advance(
        self, integrator: Integrator, t_next: float, outputs: np.ndarray | None = None, k: int = 0
    ) -> tuple[bool, float, int]:
        """Integrate to ``t_next`` or the first root: (root found, t reached, next output index).

        Without a monitor this is one CVODE call in normal mode. With one, the kernel's one-step
        loop (:meth:`~heliostep.cosim.kernel.Kernel.advance`) shows the monitor the solution after
        each internal step; with ``outputs``, the rows at ``outputs[k:]`` passed on the way
        (earlier than the time reached) are recorded by interpolation.
        """
        if self.monitor is None:
            root, t = integrator.step(t_next)
            return root, t, k
        return integrator.advance(
            t_next, outputs if outputs is not None else self._no_outputs, k, outputs is not None, self._take_rows
        )

    def _execute(self, start_time: float, stop_time: float, grid: np.ndarray) -> None:
        system = self._initialize(start_time, stop_time)
        sampled = [c.times for c in self.graph.sampled.components.values()] if self.graph.sampled is not None else []
        change_times = np.unique(np.concatenate([item.times for item in self.graph.inputs] + sampled or [np.zeros(0)]))
        change_times = change_times[(change_times > start_time) & (change_times <= stop_time)]
        self.integrator = integrator = make_integrator(
            system,
            start_time,
            self.options,
            self.input_values,
            len(self.rows.columns),
            self.monitor is not None,
        )
        kernel = getattr(integrator, "kernel", None)
        self.fast_events = events.compiled_events(self, system, integrator, kernel)
        interpolate = self.monitor is not None  # output rows from CVODE's interpolating polynomial
        samples = self.samples
        assert samples is not None
        t = start_time
        next_output = next_change = 0
        while True:
            # stops closer than this to t count as reached (CVODE cannot integrate that far)
            eps = 1e-12 * max(1.0, abs(t))
            while next_output < len(grid) and grid[next_output] <= t + eps:
                next_output += 1
            if next_change < len(change_times) and change_times[next_change] <= t + eps:
                # a change a rounding error after t (an output time just before it) takes effect here
                self._event(system, integrator, t, new_inputs=True, input_time=float(change_times[next_change]))
                next_change += 1
                continue
            if t >= stop_time - eps:
                break
            time_events = [
                u.next_event_time
                for u in system.unit_list
                if u.next_event_time is not None and u.next_event_time > t + eps
            ]
            t_output = grid[next_output] if next_output < len(grid) else stop_time
            t_change = change_times[next_change] if next_change < len(change_times) else np.inf
            t_time_event = min(time_events) if time_events else np.inf
            if interpolate:  # output times between internal steps come from interpolation
                t_next = min(t_change, t_time_event, samples.next_time, stop_time)
            else:
                t_next = min(t_output, t_change, t_time_event, samples.next_time, stop_time)
            t_next = _to_time_event(t_next, t_time_event)
            self.counts["integrator_calls"] += 1
            state_event, t, next_output, t_output = self._integrate(
                integrator, t_next, grid, next_output, t_output, interpolate
            )
            input_event = t >= t_change
            if input_event:
                next_change += 1
            self._after_step(system, integrator, t, t_output, state_event, input_event, t >= t_time_event)
            if samples.due(t) and samples.take(t):  # the controller appended changes: merged with the rest
                change_times = np.unique(np.concatenate([change_times[next_change:], samples.changes_after(t)]))
                next_change = 0
                grid, next_output = samples.outputs_after(t, grid[next_output:], stop_time), 0
                if self.fast_events is not None:
                    self.fast_events.refresh(self.graph.inputs)

    def _integrate(
        self,
        integrator: Integrator,
        t_next: float,
        grid: np.ndarray,
        next_output: int,
        t_output: float,
        interpolate: bool,
    ) -> tuple[bool, float, int, float]:
        """One solver call towards ``t_next``: (root found, t reached, next output index, the
        output time to record at the time reached or later); a callback's error re-raised."""
        try:
            if interpolate:
                state_event, t, next_output = self._advance(integrator, t_next, grid, next_output)
                # outputs at (within rounding of) the time reached: recorded there, as before
                t_output = grid[next_output] if next_output < len(grid) else np.inf
                t_output = t if t_output <= t + 1e-12 * max(1.0, abs(t)) else t_output
            else:
                state_event, t, _ = self._advance(integrator, t_next)
        except BaseException:
            self._raise_callback_error(integrator)  # the cause, not CVODE's generic failure
            raise
        self._raise_callback_error(integrator)
        return state_event, t, next_output, t_output

    def _after_step(
        self,
        system: CoupledSystem,
        integrator: Integrator,
        t: float,
        t_output: float,
        state_event: bool,
        input_event: bool,
        time_event: bool,
    ) -> None:
        """At the time reached: the FMUs' completed step, then the event there or the output row."""
        self.time = t
        # the time set and the connections copied in the kernel's event call, unless sampled components read them
        prepare = self.fast_events is not None and not system.needs_step_call and self.graph.sampled is None
        if not (prepare and (state_event or input_event or time_event)):
            system.set_time(t)
            system.propagate()
        step_event = False
        for unit in system.needs_step_call:
            enter, terminate = unit.fmu.completed_integrator_step()
            step_event |= enter
            if terminate:
                raise Terminated(
                    f"{unit.name} asked to terminate the simulation (fmi2CompletedIntegratorStep: terminateSimulation)",
                    t,
                    (unit.name,),
                )
        if state_event or step_event or input_event or time_event:
            self.counts["state_events"] += int(state_event)
            self.counts["time_events"] += int(time_event)
            if prepare:
                events.fast_event(self, t, input_event, t, prepare=True)
            else:
                self._event(system, integrator, t, new_inputs=input_event)
        elif t >= t_output:
            self.record(t)
        if self.progress:
            self.progress(t)
        if self.should_stop is not None and self.should_stop():
            raise Interrupted()


def _check_controller(graph: CoSimulation, controller: SampledController) -> None:
    """InputError for a controller's reading that is no output, or a given input whose change a derivative
    could see (its FMU has continuous states, or outputs connected to another FMU)."""
    for name in controller.reads:
        graph._variable(name, "controller reading", "output")
    for name in controller.sets:
        instance, _ = graph._variable(name, "controller input", "input")
        feeding = [c.target for c in graph.connections if c.source.startswith(f"{instance}.")]
        states = len(graph.fmus[instance].states)
        if states or feeding:
            raise InputError(
                f"controller input {name!r}: given between events, so {instance} must have no continuous state "
                f"(it has {states}) and feed no other FMU (it feeds {', '.join(feeding) or 'none'})"
            )


def _sampled_first(run: _Run, t: float) -> Terminated | None:
    """The sampled components' communication at ``t`` [s] before the kernel takes the event there (they change
    none of the row before); on a failure the trace ends with the row before, as on the Python path."""
    assert run.graph.sampled is not None
    try:
        return run.graph.sampled.communicate(t)
    except BaseException:
        run.record(t)
        raise


def _to_time_event(t_next: float, t_time_event: float) -> float:
    """The time to stop at: an output time or input change ``t_next`` [s] a rounding error before an FMU's time
    event moves to the event's own instant (the row is taken there); stopping short of it, the event would
    count as passed (within eps of the time reached) and never be handled."""
    return t_time_event if t_next < t_time_event <= t_next + 1e-12 * max(1.0, abs(t_next)) else t_next
