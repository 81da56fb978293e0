"""An event's fixed work in one call of the compiled kernel: :c:func:`hs_event`.

:class:`FastEvents` makes, from C, the FMI calls the Python path makes at an event (row before, event
mode, new inputs, the first iteration of the event update, continuous-time mode, CVODE restarted, row after),
for kinds whose calls the kernel knows (:attr:`~heliostep.cosim.kinds.Kind.fast_events`). Whenever an
FMU's answer sets a flag, or the outputs changed, the kernel stops there and the Python path goes on
(:class:`~heliostep.cosim.events.Resume`), so FMI's semantics are the Python path's.
:func:`fast_events` says whether a run's system allows it; ``statistics["compiled_events"]`` and
``["resumed_events"]`` count the events done wholly in the kernel and those the Python path finished.
"""

from __future__ import annotations

import ctypes
from typing import TYPE_CHECKING, Any

import numpy as np
from fmpy.fmi2 import fmi2EventInfo

from heliostep.cosim import sundials, watch
from heliostep.cosim.connections import split_name
from heliostep.cosim.events import Resume, discrete_fixed_point
from heliostep.cosim.kernel import Kernel, library

if TYPE_CHECKING:
    from heliostep.cosim.signals import PiecewiseConstant
    from heliostep.cosim.system import CoupledSystem

#: What :c:func:`hs_event` returns (kernel.c, the section "events").
EVENT_DONE, EVENT_GENERAL, EVENT_CHANGED = 0, 1, 2
EVENT_FAILED, EVENT_REINIT_FAILED = -1, -2


class EventUnit(ctypes.Structure):
    """kernel.c ``hs_event_unit``."""

    _fields_ = [
        (name, ctypes.c_void_p)
        for name in ("enter_event_mode", "enter_continuous_time_mode", "new_discrete_states", "get_states")
    ]


class Events(ctypes.Structure):
    """kernel.c ``hs_events``: what one run's events need, set once."""

    _fields_ = [
        ("units", ctypes.c_void_p),
        ("n_inputs", ctypes.c_long),
        ("inputs", ctypes.c_void_p),
        ("times", ctypes.c_void_p),
        ("n_times", ctypes.c_void_p),
        ("values", ctypes.c_void_p),
        ("n_targets", ctypes.c_long),
        ("target_input", ctypes.c_void_p),
        ("target_unit", ctypes.c_void_p),
        ("target_vr", ctypes.c_void_p),
        ("n_outputs", ctypes.c_long),
        ("work", ctypes.c_void_p),
        ("reinit", ctypes.c_void_p),
        ("f_enter_event", ctypes.c_long),
        ("f_new_discrete", ctypes.c_long),
        ("f_enter_continuous", ctypes.c_long),
        ("f_get_states", ctypes.c_long),
    ]


class EventArgs(ctypes.Structure):
    """kernel.c ``hs_event_args``: one call of :c:func:`hs_event`."""

    _fields_ = [
        ("t", ctypes.c_double),
        ("input_time", ctypes.c_double),
        ("new_inputs", ctypes.c_int),
        ("prepare", ctypes.c_int),
        ("cvode_mem", ctypes.c_void_p),
        ("y", ctypes.c_void_p),
        ("rows", ctypes.c_void_p),
        ("recorded", ctypes.c_long),
        ("entered", ctypes.c_long),
        ("continued", ctypes.c_long),
        ("unit", ctypes.c_long),
        ("info", fmi2EventInfo),  # kernel.c hs_event_info
        ("outputs", ctypes.c_void_p),
        ("cvode_flag", ctypes.c_int),
    ]


#: The ctypes mirror of each structure of the section, by its C name (hs_event_info: fmpy's fmi2EventInfo).
STRUCTURES: dict[str, type[ctypes.Structure]] = {
    "hs_event_info": fmi2EventInfo,
    "hs_event_unit": EventUnit,
    "hs_events": Events,
    "hs_event_args": EventArgs,
}

_bound = False


def _library() -> ctypes.CDLL:
    global _bound
    lib = library()
    if not _bound:
        lib.hs_event.argtypes = [ctypes.c_void_p, ctypes.c_void_p, ctypes.c_void_p]
        lib.hs_event.restype = ctypes.c_int
        lib.hs_event_describe.argtypes, lib.hs_event_describe.restype = [ctypes.c_char_p], ctypes.c_long
        lib.hs_event_states.argtypes = [ctypes.c_void_p] * 3 + [ctypes.c_int, ctypes.c_double]
        lib.hs_event_states.restype = ctypes.c_int
        _bound = True
    return lib


def describe(name: str) -> int:
    """The section's layout as compiled: sizeof ``"hs_events"``, offsetof ``"hs_events.units"``, a code;
    -1 if unknown."""
    return int(_library().hs_event_describe(name.encode()))


def fast_events(system: CoupledSystem, kernel: Kernel | None, compiled: bool, served: bool) -> bool:
    """Whether the run's events can go through :c:func:`hs_event` (see the module's docstring); ``served``:
    no text outputs."""
    if not (compiled and served) or kernel is None or kernel.state.prepare:
        return False
    if system.loop is not None or system.native_links is None or len(system.event_links) != len(system.links):
        return False
    graph = system.graph
    if not all(unit.info.kind.fast_events for unit in system.unit_list):
        return False
    for item in graph.inputs:
        if item.target:
            instance, variable = split_name(item.target, "input target")
            if system.units[instance].info.variable(variable).type != "Real":
                return False
    return True


class FastEvents:
    """:c:func:`hs_event` for one run: the kernel's units, the master's inputs (``inputs``: their signals;
    ``values``: the array of their current values the kernel reads), CVODE's memory and state vector."""

    def __init__(
        self,
        system: CoupledSystem,
        kernel: Kernel,
        inputs: list[PiecewiseConstant],
        values: np.ndarray,
        cvode_mem: int,
        y: int,
    ):
        self._library = _library()
        self.kernel, self.system = kernel, system
        units = system.unit_list
        self._units = (EventUnit * max(1, len(units)))()
        for k, unit in enumerate(units):
            fmu, u = unit.fmu, self._units[k]
            u.enter_event_mode = fmu.function_address("fmi2EnterEventMode")
            u.enter_continuous_time_mode = fmu.function_address("fmi2EnterContinuousTimeMode")
            u.new_discrete_states = fmu.function_address("fmi2NewDiscreteStates")
            u.get_states = fmu.function_address("fmi2GetContinuousStates")
        signals = [
            (np.ascontiguousarray(i.times, dtype=float), np.ascontiguousarray(i.values, dtype=float)) for i in inputs
        ]
        index = {name: k for k, name in enumerate(system.units)}
        targets = []
        for k, item in enumerate(inputs):
            if item.target:
                instance, variable = split_name(item.target, "input target")
                targets.append((k, index[instance], system.units[instance].info.variable(variable).value_reference))
        width = int(kernel.state.row_width)
        self.n_outputs = width - 1 - len(inputs)
        arrays: list[np.ndarray] = [
            np.array([s[0].ctypes.data for s in signals] or [0], dtype=np.uintp),  # times
            np.array([len(s[0]) for s in signals] or [0], dtype=np.int64),
            np.array([s[1].ctypes.data for s in signals] or [0], dtype=np.uintp),  # values
            np.array([t[0] for t in targets] or [0], dtype=np.int64),
            np.array([t[1] for t in targets] or [0], dtype=np.int64),
            np.array([t[2] for t in targets] or [0], dtype=np.uint32),
            np.zeros((2, width)),  # work
        ]
        self._keep = (signals, arrays, values)  # the C structure holds their addresses
        s = self.events = Events()
        s.units = ctypes.addressof(self._units)
        s.n_inputs, s.inputs = len(inputs), values.ctypes.data
        s.times, s.n_times, s.values = (a.ctypes.data for a in arrays[0:3])
        s.n_targets = len(targets)
        s.target_input, s.target_unit, s.target_vr = (a.ctypes.data for a in arrays[3:6])
        s.n_outputs, s.work = self.n_outputs, arrays[6].ctypes.data
        s.reinit = sundials.cvode_address("CVodeReInit")
        code = watch.FUNCTIONS.index
        s.f_enter_event, s.f_new_discrete = code("fmi2EnterEventMode"), code("fmi2NewDiscreteStates")
        s.f_enter_continuous, s.f_get_states = code("fmi2EnterContinuousTimeMode"), code("fmi2GetContinuousStates")
        self.rows = np.zeros((2, width))
        self.outputs = np.zeros(max(1, self.n_outputs))
        self.args = EventArgs(cvode_mem=cvode_mem, y=y, rows=self.rows.ctypes.data, outputs=self.outputs.ctypes.data)
        self._call = self._library.hs_event
        self._kernel_address = kernel.user_data.value
        self._events_address = ctypes.addressof(s)
        self._args_address = ctypes.addressof(self.args)

    def __call__(self, t: float, new_inputs: bool, input_time: float, prepare: bool) -> int:
        """:c:func:`hs_event` at ``t`` [s] (the new inputs' values from ``input_time`` on; ``prepare``: set the
        time and copy the connections first): its code; the rows before and after in :attr:`rows`."""
        args = self.args
        args.t, args.input_time, args.new_inputs, args.prepare = t, input_time, bool(new_inputs), prepare
        return self._call(self._kernel_address, self._events_address, self._args_address)

    def refresh(self, inputs: list) -> None:
        """The kernel's view of the inputs' changes after a controller appended some (their arrays may have
        moved when they grew)."""
        times, counts, values = self._keep[1][0:3]
        for k, item in enumerate(inputs):
            buffers = getattr(item, "buffers", None)
            if buffers is not None:  # a ScheduledInput
                times[k], counts[k], values[k] = buffers[0].ctypes.data, len(item.times), buffers[1].ctypes.data

    def modes_after_failure(self) -> None:
        """The instances' modes as far as the failed call got (then the error sets the failing one's)."""
        for k, unit in enumerate(self.system.unit_list):
            if k < self.args.continued:
                unit.fmu.mode = "continuous"
            elif k < self.args.entered:
                unit.fmu.mode = "event"


def compiled_events(run: Any, system: CoupledSystem, integrator: Any, kernel: Kernel | None) -> FastEvents | None:
    """The run's :class:`FastEvents` where :func:`fast_events` allows them (``run``: the master's ``_Run``;
    ``integrator``: its CVODE on ``kernel``), the integrator's states then read and set by the kernel too."""
    served = run.texts is None
    if kernel is None or not fast_events(system, kernel, integrator.compiled, served):
        return None
    fast = FastEvents(system, kernel, run.graph.inputs, run.input_values, integrator.cvode_mem, integrator.x)
    integrator.states = CompiledStates(system, fast)
    return fast


def fast_event(run: Any, t: float, new_inputs: bool, input_time: float, prepare: bool = False) -> None:
    """The master's event at ``t`` [s] through :c:func:`hs_event` (``run``: the master's ``_Run``; ``prepare``:
    the time set and the connections copied first, in the kernel): both rows stored and shown to the monitor,
    or the Python path from where the kernel stopped (:class:`~heliostep.cosim.events.Resume`); a failure
    raised as the Python path raises it."""
    system, integrator = run.system, run.integrator
    fast: FastEvents = run.fast_events
    run.counts["events"] += 1
    status = fast(t, new_inputs, input_time, prepare)
    units = system.unit_list
    if prepare:
        for unit in units:
            unit.fmu.time = t
    args = fast.args
    if status == EVENT_DONE:
        run.counts["compiled_events"] += 1
        for unit in units:
            unit.next_event_time = None
        trace = run.rows
        if trace.flush_interval is None and (trace.sink is None or trace.buffered + 2 <= trace.sink_rows):
            trace.store(fast.rows.copy())  # as one block: the same blocks handed on as two stores
        else:
            trace.store(fast.rows[:1].copy())
            trace.store(fast.rows[1:].copy())
        if run.monitor is not None:
            run.monitor(fast.rows)
        return
    if args.recorded:
        run.rows.store(fast.rows[:1].copy())
        if run.monitor is not None:
            run.monitor(fast.rows[:1])
    if status < 0:
        _raise_failure(run, fast, integrator, status)
    run.counts["resumed_events"] += 1
    for unit in units:  # all in event mode, the first iteration begun
        unit.fmu.mode = "event"
    general = status == EVENT_GENERAL
    for unit in units[: args.unit if general else len(units)]:
        unit.next_event_time = None  # their first call answered with no flag
    resume = Resume(
        fast.outputs[: fast.n_outputs].copy(), args.unit if general else None, args.info if general else None
    )
    discrete_fixed_point(system, run.time, resume=resume)
    for unit in units:
        unit.fmu.enter_continuous_time_mode()
    try:
        integrator.reset(t)
    except BaseException:
        run._raise_callback_error(integrator)
        raise
    run._raise_callback_error(integrator)
    run.record(t)


def _raise_failure(run: Any, fast: FastEvents, integrator: Any, status: int) -> None:
    """The error of a failed :c:func:`hs_event`, as the Python path would have raised it."""
    fast.modes_after_failure()
    if status == EVENT_REINIT_FAILED:
        raise RuntimeError(f"CVodeReInit failed (flag {fast.args.cvode_flag})")
    run._raise_callback_error(integrator)  # the FMU's error the kernel recorded
    raise RuntimeError("the compiled event failed without an error recorded")


class CompiledStates:
    """The coupled system's states for the integrator (:class:`~heliostep.cosim.integrator.StateAccess`):
    ``get_x``/``set_x`` in one call of the kernel (:c:func:`hs_event_states`, the same FMI calls in the
    same order as :meth:`~heliostep.cosim.system.CoupledSystem.get_x`), the nominals from the system."""

    def __init__(self, system: CoupledSystem, fast: FastEvents):
        self.system, self.fast = system, fast
        self.get_nominals = system.get_nominals
        self._call = fast._library.hs_event_states
        self._kernel, self._events = fast._kernel_address, fast._events_address
        self._units = system.unit_list  # (none: a system of sampled components only, whose states are never read)

    def get_x(self, address: int) -> None:
        if self._call(self._kernel, self._events, address, 0, self._units[0].fmu.time):
            self._raise()

    def set_x(self, address: int) -> None:
        if self._call(self._kernel, self._events, address, 1, self._units[0].fmu.time):
            self._raise()

    def _raise(self) -> None:
        taken = self.fast.kernel.take_error()
        if taken is None:
            raise RuntimeError("the compiled states call failed without an error recorded")
        raise taken[0]
