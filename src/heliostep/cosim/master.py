"""The co-simulation master: several FMI 2.0 Model Exchange FMUs solved as one system.

All continuous states of all FMUs form one vector integrated by SUNDIALS CVODE through
fmpy (:class:`fmpy.sundials.CVodeSolver`: BDF, Newton iteration, dense Jacobian). On every
right-hand-side evaluation the master sets time and states of each FMU, propagates outputs
to connected inputs in the order of the FMUs' direct feedthrough (read from their
``ModelStructure``) and collects the derivatives.

Discontinuities are handled per FMI 2.0: master-side inputs change only at known instants
(:class:`PiecewiseConstant`), where the integration stops, every FMU enters event mode, the
new inputs are set, the ``fmi2NewDiscreteStates`` iteration runs to a fixed point (outputs
re-propagated between rounds) and CVODE restarts. FMU time events (``nextEventTime``), state
events (CVODE root finding on all event indicators) and step events
(``fmi2CompletedIntegratorStep``) go through the same event handling.

Variables of every FMI 2.0 type are exchanged with their own get/set functions; connections
join compatible types only (Real with Real of the same unit, Integer/Enumeration with
Integer/Enumeration, Boolean with Boolean). Discrete-time connections (any non-Real variable,
or a Real of variability discrete on either side) are copied only at events (initialization,
event mode, the discrete fixed point), continuous ones also on every model evaluation.
An FMU asking for ``terminateSimulation`` ends the run normally at that instant
(:attr:`MasterResult.terminated`). Every instance gets ``fmi2Terminate`` (where allowed) and
``fmi2FreeInstance`` on every path. Exceptions raised inside CVODE's callbacks are kept and
re-raised after the solver call, with the time of the failing evaluation.

The trace has a row at every output time and a row just before and just after every event
(two rows with the same time), so nothing that happens at a step is lost to interpolation.

CVODE's right-hand side and root function are compiled C (:mod:`heliostep.cosim.kernel`,
switch :data:`COMPILED_RHS`): per evaluation they set time and states, copy the continuous Real
connections in the same propagation order and read derivatives or event indicators through the
FMUs' own ``fmi2*`` function pointers, with no Python per evaluation; an FMI error comes back as
a status recorded with its time and becomes the same :class:`~heliostep.cosim.fmi.FMIError`.
Runs with algebraic loops keep the Python callbacks. The event logic stays here, in Python.

With a monitor (every run of heliostep's), CVODE runs in one-step mode and the loop over its
internal steps is C too (:meth:`heliostep.cosim.kernel.Kernel.advance`): after each internal
step it records the row the monitor sees into a buffer handed over in blocks. With
:data:`INTERPOLATE_OUTPUTS` (on by default; ``HELIOSTEP_INTERPOLATE_OUTPUTS=0`` makes CVODE
stop at every output time instead) CVODE stops only at input changes, time events and the
stop time; output rows in between are recorded from CVODE's interpolating polynomial
(``CVodeGetDky``). The two paths differ by the solver's error only; the regression tubes are
set at twice it (``benchmarks/tolerance_study.py``).
"""

from __future__ import annotations

import ctypes
import os
import time as clock
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from heliostep.cosim.fmi import FMUInfo, ModelExchangeInstance, address, convert_value
from heliostep.cosim.connections import ConnectionGraph, split_name
from heliostep.cosim.loops import LoopSolver
from heliostep.cosim.signals import Connection, PiecewiseConstant, SolverOptions, cvode_failure, too_many_steps
from heliostep.errors import HeliostepError, InputError


class SimulationError(HeliostepError):
    """The simulation failed or was stopped part-way; ``trace`` holds what was computed until then.

    ``reason`` is ``"failed"`` or ``"interrupted"`` (``should_stop`` asked to stop); ``time`` is
    the simulation time reached [s].
    """

    def __init__(self, message: str, trace: pd.DataFrame, statistics: dict, reason: str = "failed",
                 time: float = float("nan")):
        super().__init__(message)
        self.trace = trace
        self.statistics = statistics
        self.reason = reason
        self.time = time


class _Interrupted(HeliostepError):
    """Raised inside the main loop when ``should_stop`` says so (between solver calls)."""


#: CVODE's one-step task and the flag it returns on reaching the stop time (cvode.h).
_CV_ONE_STEP = 2
_CV_TSTOP_RETURN = 1

#: CVODE calls the compiled right-hand side and root function (:mod:`heliostep.cosim.kernel`)
#: directly; runs with algebraic loops keep the Python callbacks.
COMPILED_RHS = os.environ.get("HELIOSTEP_COMPILED_RHS", "1") == "1"

#: With a monitor (one-step CVODE), stop the solver only at input changes, time events and the
#: stop time, and record output times that fall between internal steps from CVODE's
#: interpolating polynomial (CVodeGetDky) instead of making CVODE stop at each of them.
INTERPOLATE_OUTPUTS = os.environ.get("HELIOSTEP_INTERPOLATE_OUTPUTS", "1") == "1"


class _Terminated(HeliostepError):
    """An FMU asked to terminate the simulation (fmi2NewDiscreteStates/CompletedIntegratorStep)."""

    def __init__(self, reason: str, time: float):
        super().__init__(reason)
        self.reason = reason
        self.time = time


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


class _Unit:
    """One FMU instance and the buffers the master uses with it."""

    def __init__(self, name: str, info: FMUInfo, parameters: Mapping[str, float]):
        self.name = name
        self.info = info
        self.fmu = ModelExchangeInstance(info, name, parameters)
        self.n_states = self.fmu.n_states
        self.n_indicators = self.fmu.n_event_indicators
        self.outputs = info.traced_outputs  # every type but String, traced as floats
        self.read_outputs = self.fmu.reader(self.outputs) if self.outputs else (lambda: np.zeros(0))
        self.next_event_time: float | None = None


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
    """

    def __init__(self, fmus: Mapping[str, FMUInfo], connections: Sequence[Connection] = (),
                 inputs: Sequence[PiecewiseConstant] = (),
                 parameters: Mapping[str, Mapping[str, float]] | None = None):
        parameters = parameters or {}
        unknown = set(parameters) - set(fmus)
        if unknown:
            raise InputError(f"parameters given for unknown FMU instance(s) {sorted(unknown)}; "
                             f"instances: {', '.join(fmus)}")
        super().__init__(fmus, connections, inputs)
        self._parameters = {name: dict(parameters.get(name, {})) for name in fmus}
        for name, values in self._parameters.items():  # every value must fit its type, up front
            info = self.fmus[name]
            for parameter, value in values.items():
                if parameter in info.variables and info.variables[parameter].causality == "parameter":
                    convert_value(info.variables[parameter], value)

    # ------------------------------------------------------------------ simulation
    def simulate(self, start_time: float, stop_time: float, output_times: np.ndarray | None = None,
                 solver: SolverOptions | None = None,
                 progress: Callable[[float], None] | None = None,
                 monitor: Callable[[np.ndarray], None] | None = None,
                 should_stop: Callable[[], bool] | None = None,
                 sink: Callable[[np.ndarray], None] | None = None, sink_rows: int = 4096) -> MasterResult:
        """Integrate from ``start_time`` to ``stop_time`` [s].

        Returns the trace with a row at each of ``output_times`` (default: start and stop)
        and rows just before/after each event. On failure raises :class:`SimulationError`
        carrying the trace so far.

        ``monitor``, when given, is called with blocks of rows (2-D arrays laid out like the
        trace's rows: time, master inputs, FMU outputs; in time order; valid during the call only)
        holding a row at **every internal step of the solver**, at every event (both sides) and
        at every output time, so figures such as peaks and integrals can be
        computed from the solution itself rather than from the output grid (CVODE then runs in
        one-step mode up to each stop). ``should_stop`` is asked between solver calls; when it
        returns True the run stops there with a :class:`SimulationError` whose ``reason`` is
        ``"interrupted"``.

        ``sink``, when given, receives the trace rows as they are produced, in time order, as 2-D
        blocks (rows × the trace's columns) of at most ``sink_rows`` rows; the master then holds
        at most ``sink_rows`` rows, or one larger block stored at once, which it passes straight on
        (``statistics["max_buffered_rows"]`` is the most it held), and the trace it returns
        (or carries in :class:`SimulationError`) has the columns but no rows. The last block is
        handed over before this returns or raises, also when the run fails or is interrupted.
        """
        if not stop_time > start_time:
            raise InputError(f"stop time {stop_time} must be after start time {start_time}")
        solver = solver or SolverOptions()
        grid = np.unique(np.clip(np.asarray([start_time, stop_time] if output_times is None
                                            else output_times, dtype=float), start_time, stop_time))
        run = _Run(self, solver, progress, monitor, should_stop, sink, sink_rows)
        try:
            run.execute(start_time, stop_time, grid)
        except _Interrupted:
            raise SimulationError(f"interrupted at t = {run.time:.9g} s", run.trace(), run.statistics(),
                                  reason="interrupted", time=run.time) from None
        except (HeliostepError, RuntimeError) as exc:
            raise SimulationError(f"simulation failed at t = {run.time:.9g} s: {exc}",
                                  run.trace(), run.statistics(), time=run.time) from exc
        finally:
            run.close()
        return MasterResult(run.trace(), run.statistics(), terminated=run.terminated,
                            termination_reason=run.termination_reason, termination_time=run.termination_time)


class _Run:
    """State of one integration (instances, CVODE, recorded rows)."""

    def __init__(self, system: CoSimulation, solver: SolverOptions, progress, monitor=None, should_stop=None,
                 sink: Callable[[np.ndarray], None] | None = None, sink_rows: int = 4096):
        if sink is not None and sink_rows < 1:
            raise InputError(f"sink_rows must be at least 1, not {sink_rows}")
        self.system = system
        self.options = solver
        self.progress = progress
        self.monitor = monitor
        self.should_stop = should_stop
        self.units: dict[str, _Unit] = {}
        self.rows: list[np.ndarray] = []  # blocks of trace rows not yet handed to the sink (all without one)
        self.buffered = 0  # rows in self.rows
        self.max_buffered = 0  # the most rows held at once
        self.sink, self.sink_rows = sink, sink_rows
        self.time = np.nan
        self.counts = {"rhs": 0, "integrator_calls": 0, "events": 0, "state_events": 0, "time_events": 0,
                       "nominal_reads": 0}
        self.nominals: np.ndarray | None = None  # the states' nominals as last read (get_nominals)
        self.nominals_changed = False  # an event said they changed: read them again
        self.wall_start = clock.perf_counter()
        self.terminated, self.termination_reason, self.termination_time = False, "", None
        self.callback_error: BaseException | None = None  # raised inside a CVODE callback
        self.callback_time = np.nan
        self.kernel = None  # the compiled right-hand side, when CVODE uses it
        self._dky = None  # CVODE's interpolated states at an output time (one-step mode)
        self._no_outputs = np.zeros(0)
        self.input_values = np.array([item.values[0] for item in system.inputs], dtype=float)
        self.columns = ["time"] + [item.name for item in system.inputs]
        for name, info in system.fmus.items():
            self.columns += [f"{name}.{output}" for output in info.traced_outputs]

    # --------------------------------------------------------------- setup
    def _instantiate(self, start_time: float) -> None:
        self.units_list = []
        for name, info in self.system.fmus.items():
            self.units[name] = unit = _Unit(name, info, self.system._parameters[name])
            unit.fmu.setup_experiment(start_time)
            unit.fmu.enter_initialization_mode()
        self.units_list = list(self.units.values())
        self.offsets = np.cumsum([0] + [u.n_states for u in self.units_list])
        self.z_offsets = np.cumsum([0] + [u.n_indicators for u in self.units_list])
        self.n_states = int(self.offsets[-1])
        self.n_indicators = int(self.z_offsets[-1])
        self.input_writers = []
        for k, item in enumerate(self.system.inputs):
            instance, variable = split_name(item.target, "input target")
            self.input_writers.append((k, self.units[instance].fmu.writer([variable])))
        self.links, self.event_links = [], []  # continuous ones; all (at events)
        self.native_links = []  # the continuous ones for the compiled kernel (None: not all Real)
        index = {name: k for k, name in enumerate(self.units)}
        for source, target, connections in self.system.propagation_groups():
            for discrete in (False, True):
                members = [c for c in connections if self.system.is_discrete(c) == discrete]
                if not members:
                    continue
                outputs = [split_name(c.source, "source")[1] for c in members]
                inputs = [split_name(c.target, "target")[1] for c in members]
                link = self.units[source].fmu.link(outputs, self.units[target].fmu, inputs)
                self.event_links.append(link)
                if not discrete:
                    self.links.append(link)
                    source_fmu, target_fmu = self.units[source].fmu, self.units[target].fmu
                    real = all(source_fmu.info.variable(o).type == "Real" for o in outputs) and all(
                        target_fmu.info.variable(i).type == "Real" for i in inputs)
                    if self.native_links is not None and real:
                        self.native_links.append((index[source], index[target], source_fmu.value_references(outputs),
                                                  target_fmu.value_references(inputs)))
                    else:
                        self.native_links = None
        self.loop = None
        if self.system.torn:  # algebraic loops: Newton on the torn inputs at every propagation
            ends = [(split_name(c.target, "target"), split_name(c.source, "source")) for c in self.system.torn]
            writers = [self.units[i].fmu.writer([v]) for (i, v), _ in ends]
            readers = [self.units[i].fmu.reader([v]) for _, (i, v) in ends]

            def write(values) -> None:
                for put, value in zip(writers, values):
                    put([value])

            def read() -> np.ndarray:
                return np.array([get()[0] for get in readers])
            self.loop = LoopSolver([c.target for c in self.system.torn], write, read)
        self.needs_step_call = [u for u in self.units_list if u.info.needs_completed_integrator_step]
        # (unit, byte offset of its states, of its event indicators) for the CVODE callbacks
        self.state_units = [(u, 8 * int(lo)) for u, lo in zip(self.units_list, self.offsets[:-1]) if u.n_states]
        self.indicator_units = [(u, 8 * int(lo)) for u, lo in zip(self.units_list, self.z_offsets[:-1])
                                if u.n_indicators]

    def _apply_inputs(self) -> None:
        for k, write in self.input_writers:
            write([self.input_values[k]])

    def _propagate(self) -> None:
        """Continuous-time connections (continuous-time mode: every model evaluation)."""
        if self.loop is not None:
            self.loop.solve(self._copy_continuous, self.time)
            return
        for copy in self.links:
            copy()

    def _copy_continuous(self) -> None:
        for copy in self.links:
            copy()

    def _propagate_at_event(self) -> None:
        """Every connection, discrete ones included (initialization and event mode only)."""
        if self.loop is not None:
            self.loop.solve(self._copy_all, self.time)
            return
        for copy in self.event_links:
            copy()

    def _copy_all(self) -> None:
        for copy in self.event_links:
            copy()

    def _raise_callback_error(self) -> None:
        """Re-raise what a CVODE callback raised (kept by :class:`_Solver`, or recorded by the
        compiled kernel as an FMI status), at its time."""
        if self.kernel is not None and self.callback_error is None:
            failed = self.kernel.take_error()
            if failed is not None:
                self.callback_error, self.callback_time = failed
        if self.callback_error is not None:
            error, self.callback_error = self.callback_error, None
            self.time = self.callback_time
            raise error

    # --------------------------------------------------------------- CVODE callbacks
    # CVODE hands over pointers to its vectors; the FMUs read and write them in place.
    def get_x(self, pointer, n):
        base = address(pointer)
        for unit, offset in self.state_units:
            unit.fmu.get_states_at(base + offset)

    def set_x(self, pointer, n):
        base = address(pointer)
        for unit, offset in self.state_units:
            unit.fmu.set_states_at(base + offset)

    def get_dx(self, pointer, n):
        self.counts["rhs"] += 1
        self._propagate()
        base = address(pointer)
        for unit, offset in self.state_units:
            unit.fmu.get_derivatives_at(base + offset)

    def get_z(self, pointer, n):
        self._propagate()
        base = address(pointer)
        for unit, offset in self.indicator_units:
            unit.fmu.get_event_indicators_at(base + offset)

    def get_nominals(self, pointer, n):
        """The states' nominals (CVODE's atol = rtol * nominal): read from the FMUs at the start
        and after an event whose fmi2NewDiscreteStates said nominalsOfContinuousStatesChanged
        (FMI 2.0: they change at no other time), else the values read last."""
        nominals = self._view(pointer, n)
        if self.nominals is None or self.nominals_changed:
            read = np.empty(n)
            for unit, lo, hi in self._slices():
                if unit.n_states:
                    read[lo:hi] = unit.fmu.get_nominals()
            if self.options.atol is not None:  # CVodeSolver uses atol = rtol * nominal
                read[:] = self.options.atol / self.options.rtol
            self.nominals, self.nominals_changed = read, False
            self.counts["nominal_reads"] += 1
        nominals[:] = self.nominals

    def set_time(self, t):
        for unit in self.units_list:
            unit.fmu.set_time(t)

    def apply(self, t):  # the 'input' object CVodeSolver calls in its root function
        pass

    def _slices(self):
        return zip(self.units_list, self.offsets[:-1], self.offsets[1:])

    @staticmethod
    def _view(pointer, n):
        return np.ctypeslib.as_array(pointer, (n,))

    # --------------------------------------------------------------- recording
    def _row(self, t: float) -> np.ndarray:
        parts = [np.array([t]), self.input_values.copy()]
        parts += [unit.read_outputs() for unit in self.units_list]
        return np.concatenate(parts)

    def record(self, t: float) -> None:
        row = self._row(t)[None, :]
        self._store(row)
        if self.monitor is not None:
            self.monitor(row)

    def _store(self, rows: np.ndarray) -> None:
        """Every trace row goes through here: ``rows`` is a 2-D block (rows × ``self.columns``)
        in time order. Without a sink the rows are kept for :meth:`trace`; with one they are
        handed over in blocks of at most ``sink_rows`` once that many are held."""
        rows = np.asarray(rows, dtype=float)
        if rows.ndim != 2 or rows.shape[1] != len(self.columns):
            raise ValueError(f"trace rows must be a 2-D block of {len(self.columns)} columns, got shape {rows.shape}")
        if self.sink is not None and self.buffered + len(rows) > self.sink_rows:
            self._flush()  # what is held goes first: held rows never exceed sink_rows or one block
        self.rows.append(rows)
        self.buffered += len(rows)
        self.max_buffered = max(self.max_buffered, self.buffered)
        if self.sink is not None and self.buffered >= self.sink_rows:
            self._flush()

    def _flush(self) -> None:
        """Hand the held rows to the sink, in blocks of at most ``sink_rows``."""
        if self.sink is None or not self.buffered:
            return
        data = np.vstack(self.rows)
        self.rows, self.buffered = [], 0
        for start in range(0, len(data), self.sink_rows):
            self.sink(data[start:start + self.sink_rows])

    def _take_rows(self, rows: np.ndarray, kinds: np.ndarray) -> None:
        """Rows from the compiled one-step loop: all to the monitor, the output rows (kind 1) to
        the trace; then ``should_stop`` is asked (on a stop, the last row ends the trace)."""
        if self.monitor is not None:
            self.monitor(rows)
        outputs = kinds == 1
        if outputs.any():
            self._store(rows[outputs].copy())
        self.time = float(rows[-1, 0])
        if self.should_stop is not None and self.should_stop():
            if kinds[-1] != 1:  # the trace ends where the run stops: at the last solution row
                self._store(rows[-1:].copy())
            raise _Interrupted()

    def _interpolate_outputs(self, solver, outputs: np.ndarray, k: int, t: float, final: bool = True) -> int:
        """Record the rows at ``outputs[k:]`` earlier than ``t`` (the time CVODE just reached)
        from CVODE's interpolating polynomial; return the index of the first output not recorded.

        For each such output time the interpolated states and the time are set into the FMUs,
        the connections propagated and the row recorded (monitor included); the caller restores
        the states at ``t`` afterwards. ``should_stop`` is asked after each row.
        """
        eps = 1e-12 * max(1.0, abs(t))
        # after a step that is not the last, outputs within rounding of it are taken too (as in
        # the C kernel's hs_advance): CVODE interpolates only over its last step
        end = t - eps if final else t + eps
        if k >= len(outputs) or not (outputs[k] < end if final else outputs[k] <= end):
            return k
        from fmpy.sundials.cvode import sundials_cvode

        if self._dky is None:
            from fmpy.sundials.nvector_serial import N_VNew_Serial, NV_DATA_S

            get_dky = sundials_cvode.CVodeGetDky
            get_dky.argtypes = [ctypes.c_void_p, ctypes.c_double, ctypes.c_int, type(solver.x)]
            get_dky.restype = ctypes.c_int
            self._dky = N_VNew_Serial(solver.nx, solver.sunctx)
            self._dky_owner = solver  # the vector belongs to this solver's SUNDIALS context
            self._pdky = NV_DATA_S(self._dky)
        get_dky = sundials_cvode.CVodeGetDky
        while k < len(outputs) and (outputs[k] < end if final else outputs[k] <= end):
            g = float(outputs[k])
            if not solver.discrete:
                flag = get_dky(solver.cvode_mem, min(g, t), 0, self._dky)
                if flag < 0:
                    raise RuntimeError(f"CVodeGetDky at t = {g:.9g} s failed (flag {flag}) after a step to "
                                       f"t = {t:.9g} s")
            if not solver.discrete:
                self.set_x(self._pdky, solver.nx)
            self.set_time(g)
            self._propagate()
            self.record(g)
            k += 1
            if self.should_stop is not None and self.should_stop():
                self.time = g
                raise _Interrupted()
        return k

    def _advance(self, solver, t_next: float, outputs: np.ndarray | None = None, k: int = 0):
        """Integrate to ``t_next`` or the first root: (root found, t reached, next output index).

        Without a monitor this is one CVODE call in normal mode. With one and the compiled kernel,
        :meth:`~heliostep.cosim.kernel.Kernel.advance` runs the loop below in C. Otherwise CVODE takes one
        internal step at a time (stop time ``t_next``, so it never steps past it) and the
        monitor sees the solution after each. With ``outputs`` (one-step mode only), the rows
        at ``outputs[k:]`` passed on the way (earlier than the time reached) are recorded by
        interpolation (:meth:`_interpolate_outputs`).
        """
        if self.monitor is None:
            root, _, t = solver.step(self.time, t_next)
            return root, t, k
        if self.kernel is not None:  # the loop over internal steps in C
            return self.kernel.advance(solver, t_next, outputs if outputs is not None else self._no_outputs, k,
                                       outputs is not None, self.options.max_num_steps, self._take_rows)
        from fmpy.sundials.cvode import CV_ROOT_RETURN, CVode, sundials_cvode

        set_stop_time = sundials_cvode.CVodeSetStopTime
        set_stop_time.argtypes, set_stop_time.restype = [ctypes.c_void_p, ctypes.c_double], ctypes.c_int
        if not solver.discrete:
            solver.get_x(solver.px, solver.nx)
        if set_stop_time(solver.cvode_mem, t_next) < 0:
            raise RuntimeError(f"CVodeSetStopTime({t_next}) failed")
        reached = ctypes.c_double(0.0)
        steps = 0
        while True:
            steps += 1
            if steps > self.options.max_num_steps:  # as CVODE's own limit in normal mode (mxstep)
                raise too_many_steps(self.options.max_num_steps, t_next, reached.value)
            flag = CVode(solver.cvode_mem, t_next, solver.x, ctypes.byref(reached), _CV_ONE_STEP)
            if flag < 0:
                raise cvode_failure(solver.error_info, flag)
            t = reached.value
            final = flag == CV_ROOT_RETURN or flag == _CV_TSTOP_RETURN or t >= t_next
            if outputs is not None:
                k = self._interpolate_outputs(solver, outputs, k, t, final)
            if final:
                if not solver.discrete:
                    solver.set_x(solver.px, solver.nx)
                return flag == CV_ROOT_RETURN, t, k
            if not solver.discrete:
                solver.set_x(solver.px, solver.nx)
            self.set_time(t)
            self._propagate()
            self.monitor(self._row(t)[None, :])

    def trace(self) -> pd.DataFrame:
        """The rows held (all of them without a sink; none with one: they are flushed to it)."""
        self._flush()
        data = np.vstack(self.rows) if self.rows else np.zeros((0, len(self.columns)))
        return pd.DataFrame(data, columns=self.columns)

    def statistics(self) -> dict:
        counts = dict(self.counts)
        if getattr(self, "kernel", None) is not None:
            counts["rhs"] += self.kernel.rhs_count
        return {**counts, "compiled_rhs": getattr(self, "kernel", None) is not None, "wall_time": clock.perf_counter() - self.wall_start,
                "states": getattr(self, "n_states", 0), "event_indicators": getattr(self, "n_indicators", 0),
                "terminated": self.terminated, "termination_reason": self.termination_reason,
                "termination_time": self.termination_time, "algebraic_loops": list(self.system.loops),
                "max_buffered_rows": self.max_buffered,
                **(self.loop.statistics() if getattr(self, "loop", None) is not None else {})}

    # --------------------------------------------------------------- events
    def _event_iteration(self, t: float, new_inputs: bool) -> None:
        """Event mode at ``t``: set inputs, iterate discrete states to a fixed point."""
        self.counts["events"] += 1
        for unit in self.units_list:
            unit.fmu.enter_event_mode()
        if new_inputs:
            self.input_values[:] = [item.value_at(t) for item in self.system.inputs]  # in place: the kernel reads it
            self._apply_inputs()
        self._discrete_fixed_point()
        for unit in self.units_list:
            unit.fmu.enter_continuous_time_mode()

    def _discrete_fixed_point(self, max_rounds: int = 100) -> bool:
        """NewDiscreteStates on every FMU, re-propagating outputs, until nothing changes.

        The outputs are compared with those the round propagated from (read before the first
        round): when NewDiscreteStates changed none, the inputs set from them are consistent
        and one round is the fixed point (a step instant of the shipped drive needs one)."""
        changed = False
        previous = np.concatenate([unit.read_outputs() for unit in self.units_list] or [np.zeros(0)])
        for _ in range(max_rounds):
            self._propagate_at_event()
            stop = []
            for unit in self.units_list:
                result = unit.fmu.update_discrete_states()
                changed |= result.states_changed
                self.nominals_changed |= result.nominals_changed
                unit.next_event_time = result.next_event_time
                if result.terminate:
                    stop.append(unit.name)
            if stop:  # the round is complete: pass the final outputs on, then end the run
                self._propagate_at_event()
                raise _Terminated(f"{', '.join(stop)} asked to terminate the simulation "
                                  "(fmi2NewDiscreteStates: terminateSimulation)", self.time)
            outputs = np.concatenate([unit.read_outputs() for unit in self.units_list] or [np.zeros(0)])
            if np.array_equal(outputs, previous):
                return changed
            previous = outputs
        raise HeliostepError(f"event iteration at t = {self.time} found no fixed point in {max_rounds} rounds")

    # --------------------------------------------------------------- main loop
    def execute(self, start_time: float, stop_time: float, grid: np.ndarray) -> None:
        """Run the integration; an FMU's terminateSimulation ends it normally at that time."""
        try:
            self._execute(start_time, stop_time, grid)
        except _Terminated as stop:
            self.terminated, self.termination_reason, self.termination_time = True, stop.reason, stop.time
            self.record(stop.time)

    def _execute(self, start_time: float, stop_time: float, grid: np.ndarray) -> None:
        self.time = start_time
        self._instantiate(start_time)
        self._apply_inputs()
        self._propagate_at_event()
        for unit in self.units_list:
            unit.fmu.exit_initialization_mode()
        self._discrete_fixed_point()
        for unit in self.units_list:
            unit.fmu.enter_continuous_time_mode()
        self.record(start_time)

        change_times = np.unique(np.concatenate(
            [item.times for item in self.system.inputs] or [np.zeros(0)]))
        change_times = change_times[(change_times > start_time) & (change_times <= stop_time)]
        solver = self._native_solver(start_time)
        solver = solver or _Solver(
            self,
            nx=self.n_states, nz=self.n_indicators, get_x=self.get_x, set_x=self.set_x,
            get_dx=self.get_dx, get_z=self.get_z, get_nominals=self.get_nominals,
            set_time=self.set_time, input=self, startTime=start_time,
            maxStep=self.options.max_step, relativeTolerance=self.options.rtol,
            maxNumSteps=self.options.max_num_steps)

        interpolate = self.monitor is not None and INTERPOLATE_OUTPUTS
        t = start_time
        next_output = next_change = 0
        while True:
            # stops closer than this to t count as reached (CVODE cannot integrate that far)
            eps = 1e-12 * max(1.0, abs(t))
            while next_output < len(grid) and grid[next_output] <= t + eps:
                next_output += 1
            if next_change < len(change_times) and change_times[next_change] <= t + eps:
                next_change += 1
                self._event(solver, t, new_inputs=True)
                continue
            if t >= stop_time - eps:
                break
            time_events = [u.next_event_time for u in self.units_list
                           if u.next_event_time is not None and u.next_event_time > t + eps]
            t_output = grid[next_output] if next_output < len(grid) else stop_time
            t_change = change_times[next_change] if next_change < len(change_times) else np.inf
            t_time_event = min(time_events) if time_events else np.inf
            if interpolate:  # output times between internal steps come from interpolation
                t_next = min(t_change, t_time_event, stop_time)
            else:
                t_next = min(t_output, t_change, t_time_event, stop_time)

            self.counts["integrator_calls"] += 1
            try:
                if interpolate:
                    state_event, t, next_output = self._advance(solver, t_next, grid, next_output)
                    # outputs at (within rounding of) the time reached: recorded there, as before
                    t_output = grid[next_output] if next_output < len(grid) else np.inf
                    t_output = t if t_output <= t + 1e-12 * max(1.0, abs(t)) else t_output
                else:
                    state_event, t, _ = self._advance(solver, t_next)
            except BaseException:
                self._raise_callback_error()  # the cause, not CVODE's generic failure
                raise
            self._raise_callback_error()
            self.time = t
            self.set_time(t)
            self._propagate()
            step_event = False
            for unit in self.needs_step_call:
                enter, terminate = unit.fmu.completed_integrator_step()
                step_event |= enter
                if terminate:
                    raise _Terminated(f"{unit.name} asked to terminate the simulation "
                                      "(fmi2CompletedIntegratorStep: terminateSimulation)", t)

            input_event = t >= t_change
            time_event = t >= t_time_event
            if input_event:
                next_change += 1
            if state_event or step_event or input_event or time_event:
                self.counts["state_events"] += int(state_event)
                self.counts["time_events"] += int(time_event)
                self._event(solver, t, new_inputs=input_event)
            elif t >= t_output:
                self.record(t)
            if self.progress:
                self.progress(t)
            if self.should_stop is not None and self.should_stop():
                raise _Interrupted()

    def _native_solver(self, start_time: float):
        """CVODE on the compiled kernel, or None where the Python callbacks are needed
        (switched off, algebraic loops, non-Real continuous connections)."""
        if not COMPILED_RHS or self.loop is not None or self.native_links is None:
            return None
        from heliostep.cosim.kernel import Kernel, NativeSolver

        units, column = [], 1 + len(self.input_values)
        for u, x, z in zip(self.units_list, self.offsets[:-1], self.z_offsets[:-1]):
            outputs = [(u.info.variable(name).type, u.info.variable(name).value_reference, column + j)
                       for j, name in enumerate(u.outputs)]
            column += len(outputs)
            units.append((u.fmu, int(x), int(z), outputs))
        self.kernel = Kernel(units, self.native_links, self.n_states, inputs=self.input_values,
                             row_width=len(self.columns))
        return NativeSolver(self.kernel, nx=self.n_states, nz=self.n_indicators, get_x=self.get_x,
                            set_x=self.set_x, get_nominals=self.get_nominals, startTime=start_time,
                            maxStep=self.options.max_step, relativeTolerance=self.options.rtol,
                            maxNumSteps=self.options.max_num_steps)

    def _event(self, solver, t: float, new_inputs: bool) -> None:
        """Record the row before, handle the event at ``t``, restart CVODE, record the row after."""
        self.record(t)
        self._event_iteration(t, new_inputs=new_inputs)
        try:
            solver.reset(t)  # re-reads the states (changed or not) and restarts CVODE
        except BaseException:
            self._raise_callback_error()
            raise
        self._raise_callback_error()
        self.record(t)

    def close(self) -> None:
        """fmi2Terminate (where allowed) and fmi2FreeInstance for every instance, on every path."""
        for unit in self.units.values():
            unit.fmu.close()
        if getattr(self, "_dky", None) is not None:
            from fmpy.sundials.nvector_serial import N_VDestroy_Serial

            N_VDestroy_Serial(self._dky)
            self._dky = self._dky_owner = None


def _solver_class():
    from fmpy.sundials import CVodeSolver

    class Solver(CVodeSolver):
        """fmpy's CVODE wrapper whose callbacks never lose an exception: the first one is kept
        on the run (with the time of the failing evaluation) and CVODE is told to stop (-1,
        unrecoverable); the master re-raises it after the solver call."""

        def __init__(self, run: _Run, **kwargs):
            self.run = run
            super().__init__(**kwargs)

        def _guard(self, method, t, *args):
            if self.run.callback_error is not None:
                return -1
            try:
                return method(t, *args)
            except BaseException as exc:  # noqa: BLE001 - kept and re-raised outside the callback
                self.run.callback_error, self.run.callback_time = exc, float(t)
                return -1

        def f(self, t, y, ydot, user_data):
            return self._guard(super().f, t, y, ydot, user_data)

        def g(self, t, y, gout, user_data):
            return self._guard(super().g, t, y, gout, user_data)
    return Solver


def _Solver(run: _Run, **kwargs):
    return _solver_class()(run, **kwargs)
