"""The coupled system of one run: the FMU instances, their connections, loops and states as one.

:class:`CoupledSystem` instantiates every FMU of a checked
:class:`~heliostep.cosim.connections.ConnectionGraph` (up to initialization mode), builds the
calls that copy the connections in propagation order (continuous ones on every model
evaluation, all of them at events) and the Newton solver of torn algebraic loops
(:class:`~heliostep.cosim.loops.LoopSolver`), and offers all the FMUs' continuous states,
derivatives, event indicators and nominals as one vector at an address of doubles: what the
integrator (:mod:`heliostep.cosim.integrator`) reads and sets, and what the compiled kernel is
built from (:meth:`CoupledSystem.kernel_units`). It owns no solver and records no row.
"""

from __future__ import annotations

import ctypes
from collections.abc import Callable, Mapping
from typing import TYPE_CHECKING, Any

import numpy as np

from heliostep.cosim.connections import split_name
from heliostep.cosim.description import FMUInfo
from heliostep.cosim.loops import LoopSolver
from heliostep.cosim.signals import SolverOptions

if TYPE_CHECKING:
    from heliostep.cosim.connections import ConnectionGraph
    from heliostep.cosim.instance import ModelExchangeBase
    from heliostep.cosim.kernel import KernelLink, KernelLoop, KernelUnit


class Unit:
    """One FMU instance of the system and what the master reads of it."""

    def __init__(self, name: str, info: FMUInfo, parameters: Mapping[str, Any], index: int = -1):
        self.name = name
        self.info = info
        self.fmu: ModelExchangeBase = info.kind.instance_class()(info, name, parameters, index=index)
        self.n_states = self.fmu.n_states
        self.n_indicators = self.fmu.n_event_indicators
        self.outputs = info.traced_outputs  # every type but String, traced as floats
        self.read_outputs = self.fmu.reader(self.outputs) if self.outputs else (lambda: np.zeros(0))
        self.next_event_time: float | None = None


class CoupledSystem:
    """The instances of ``graph``'s FMUs in initialization mode at ``start_time`` [s], connected.

    ``parameters`` are the values per instance, ``input_values`` the array the master keeps its
    inputs' current values in (changed in place). ``time`` is the FMUs' time [s], as last set (the
    time of the evaluation an algebraic loop is solved for). An error while instantiating frees the
    instances made so far.
    """

    def __init__(
        self,
        graph: ConnectionGraph,
        parameters: Mapping[str, Mapping[str, Any]],
        start_time: float,
        input_values: np.ndarray,
        options: SolverOptions,
    ):
        self.graph, self.options, self.time = graph, options, start_time
        self.input_values = input_values
        self.units: dict[str, Unit] = {}
        self.rhs_evaluations = 0  # get_dx calls (the Python right-hand side)
        self.nominal_reads = 0
        self.nominals: np.ndarray | None = None  # the states' nominals as last read (get_nominals)
        self.nominals_changed = False  # an event said they changed: read them again
        try:
            for index, (name, info) in enumerate(graph.fmus.items()):  # index: the kernel's unit order
                self.units[name] = unit = Unit(name, info, parameters.get(name, {}), index)
                unit.fmu.setup_experiment(start_time)
                unit.fmu.enter_initialization_mode()
            self.unit_list = list(self.units.values())
            self.offsets = np.cumsum([0] + [u.n_states for u in self.unit_list])
            self.z_offsets = np.cumsum([0] + [u.n_indicators for u in self.unit_list])
            self.n_states = int(self.offsets[-1])
            self.n_indicators = int(self.z_offsets[-1])
            self.input_writers = []
            for k, item in enumerate(graph.inputs):
                if not item.target:  # traced only
                    continue
                instance, variable = split_name(item.target, "input target")
                self.input_writers.append((k, self.units[instance].fmu.writer([variable])))
            self._connect()
            self.loop = self._loop_solver()
        except BaseException:
            self.close()
            raise
        self.needs_step_call = [u for u in self.unit_list if u.info.needs_completed_integrator_step]
        # (unit, byte offset of its states, of its event indicators) in the coupled vectors
        self.state_units = [(u, 8 * int(lo)) for u, lo in zip(self.unit_list, self.offsets[:-1]) if u.n_states]
        self.indicator_units = [
            (u, 8 * int(lo)) for u, lo in zip(self.unit_list, self.z_offsets[:-1]) if u.n_indicators
        ]

    def _connect(self) -> None:
        """The copy calls of every connection group: ``links`` (continuous), ``event_links`` (all)
        and ``native_links`` (the continuous ones for the compiled kernel; None: not all Real)."""
        self.links: list[Callable[[], None]] = []
        self.event_links: list[Callable[[], None]] = []
        self.native_links: list[KernelLink] | None = []
        index = {name: k for k, name in enumerate(self.units)}
        for source, target, connections in self.graph.propagation_groups():
            for discrete in (False, True):
                members = [c for c in connections if self.graph.is_discrete(c) == discrete]
                if not members:
                    continue
                outputs = [split_name(c.source, "source")[1] for c in members]
                inputs = [split_name(c.target, "target")[1] for c in members]
                transforms = [c.transform for c in members]
                source_fmu, target_fmu = self.units[source].fmu, self.units[target].fmu
                link = source_fmu.link(outputs, target_fmu, inputs, transforms)
                self.event_links.append(link)
                if discrete:
                    continue
                self.links.append(link)
                real = all(source_fmu.info.variable(o).exchanged_as_real for o in outputs) and all(
                    target_fmu.info.variable(i).exchanged_as_real for i in inputs
                )  # FMI 3.0 Float32 too: the adapter converts it (fmi3_types)
                if self.native_links is not None and real:
                    self.native_links.append(
                        (
                            index[source],
                            index[target],
                            source_fmu.value_references(outputs),
                            target_fmu.value_references(inputs),
                            transforms if any(t not in (None, (1.0, 0.0)) for t in transforms) else None,
                        )
                    )
                else:
                    self.native_links = None

    def _loop_solver(self) -> LoopSolver | None:
        """Newton on the torn inputs at every propagation, when the graph has algebraic loops."""
        if not self.graph.torn:
            return None
        ends = [(split_name(c.target, "target"), split_name(c.source, "source")) for c in self.graph.torn]
        writers = [self.units[i].fmu.writer([v]) for (i, v), _ in ends]
        readers = [self.units[i].fmu.reader([v]) for _, (i, v) in ends]
        transforms = [c.transform if c.transform not in (None, (1.0, 0.0)) else None for c in self.graph.torn]

        def write(values: np.ndarray) -> None:
            for put, value in zip(writers, values):
                put([value])

        def read() -> np.ndarray:  # the torn sources' outputs as their inputs get them
            values = [get()[0] for get in readers]
            return np.array([v if t is None else t[0] * v + t[1] for v, t in zip(values, transforms)])

        options = self.options
        return LoopSolver([c.target for c in self.graph.torn], write, read, options.loop_rtol, options.loop_atol)

    # --------------------------------------------------------------- inputs and propagation
    def apply_inputs(self) -> None:
        """Set the master inputs' current values (``input_values``) into the FMUs."""
        for k, write in self.input_writers:
            write([self.input_values[k]])

    def propagate(self) -> None:
        """Continuous-time connections (continuous-time mode: every model evaluation)."""
        if self.loop is not None:
            self.loop.solve(self._copy_continuous, self.time)
            return
        for copy in self.links:
            copy()

    def _copy_continuous(self) -> None:
        for copy in self.links:
            copy()

    def propagate_at_event(self) -> None:
        """Every connection, discrete ones included (initialization and event mode only)."""
        if self.loop is not None:
            self.loop.solve(self._copy_all, self.time)
            return
        for copy in self.event_links:
            copy()

    def _copy_all(self) -> None:
        for copy in self.event_links:
            copy()

    def outputs(self) -> np.ndarray:
        """Every unit's traced outputs, in the order of the trace's columns."""
        return np.concatenate([unit.read_outputs() for unit in self.unit_list] or [np.zeros(0)])

    def row(self, t: float) -> np.ndarray:
        """The trace row at ``t`` [s] of the FMUs as they are: time, master inputs, traced outputs."""
        parts = [np.array([t]), self.input_values.copy()]
        parts += [unit.read_outputs() for unit in self.unit_list]
        return np.concatenate(parts)

    # --------------------------------------------------------------- the coupled vectors
    # CVODE hands over addresses of its vectors' data; the FMUs read and write them in place.
    def get_x(self, address: int) -> None:
        for unit, offset in self.state_units:
            unit.fmu.get_states_at(address + offset)

    def set_x(self, address: int) -> None:
        for unit, offset in self.state_units:
            unit.fmu.set_states_at(address + offset)

    def get_dx(self, address: int) -> None:
        self.rhs_evaluations += 1
        self.propagate()
        for unit, offset in self.state_units:
            unit.fmu.get_derivatives_at(address + offset)

    def get_z(self, address: int) -> None:
        self.propagate()
        for unit, offset in self.indicator_units:
            unit.fmu.get_event_indicators_at(address + offset)

    def get_nominals(self, address: int, n: int) -> None:
        """The states' nominals (CVODE's atol = rtol * nominal): read from the FMUs at the start
        and after an event whose fmi2NewDiscreteStates said nominalsOfContinuousStatesChanged
        (FMI 2.0: they change at no other time), else the values read last."""
        nominals = np.ctypeslib.as_array((ctypes.c_double * n).from_address(address))
        if self.nominals is None or self.nominals_changed:
            read = np.empty(n)
            for unit, lo, hi in zip(self.unit_list, self.offsets[:-1], self.offsets[1:]):
                if unit.n_states:
                    read[lo:hi] = unit.fmu.get_nominals()
            if self.options.atol is not None:  # atol = rtol * nominal
                read[:] = self.options.atol / self.options.rtol
            self.nominals, self.nominals_changed = read, False
            self.nominal_reads += 1
        nominals[:] = self.nominals

    def set_time(self, t: float) -> None:
        self.time = t
        for unit in self.unit_list:
            unit.fmu.set_time(t)

    def prepare_row(self, t: float, x: int | None) -> None:
        """The FMUs at (``t``, the states at address ``x``; None: no states) with the connections
        propagated: the kernel's ``prepare`` for a row of its one-step loop."""
        if x is not None:
            self.set_x(x)
        self.set_time(t)
        self.propagate()

    # --------------------------------------------------------------- for the compiled kernel
    def kernel_units(self) -> list[KernelUnit]:
        """The units for :class:`~heliostep.cosim.kernel.Kernel`: (instance, state offset,
        indicator offset, traced outputs as (FMI type, value reference, column of the row))."""
        units: list[KernelUnit] = []
        column = 1 + len(self.input_values)
        for u, x, z in zip(self.unit_list, self.offsets[:-1], self.z_offsets[:-1]):
            outputs = [  # an FMI 3.0 slot (array element, Float32, Int8 ...) is read as a double (fmi3_types)
                (
                    "Real" if u.info.variable(name).through_slot else u.info.variable(name).type,
                    u.info.variable(name).value_reference,
                    column + j,
                )
                for j, name in enumerate(u.outputs)
            ]
            column += len(outputs)
            units.append((u.fmu, int(x), int(z), outputs))
        return units

    def kernel_loop(self) -> tuple[list[KernelLink], KernelLoop] | None:
        """The continuous links and the algebraic loops for :class:`~heliostep.cosim.kernel.Kernel`, or
        None when there are no loops, a continuous connection is not Real or a torn one is not Real to Real
        or transforms its value.

        The loops: the solver, per torn connection (target unit index, target value reference, source
        unit index, source value reference) and the index of the first link that depends on the torn
        inputs. The links: :attr:`native_links` with those that do not depend on the torn inputs
        first (their relative order kept): a link depends on them when its source is a torn input's
        unit or the target of a link that does (by unit: conservative)."""
        if self.loop is None or self.native_links is None:
            return None
        index = {name: k for k, name in enumerate(self.units)}
        torn = []
        for c in self.graph.torn:
            (target, input_), (source, output) = split_name(c.target, "target"), split_name(c.source, "source")
            ends = self.units[target].info.variable(input_), self.units[source].info.variable(output)
            if any(end.type != "Real" for end in ends) or c.transform not in (None, (1.0, 0.0)):
                return None
            torn.append((index[target], ends[0].value_reference, index[source], ends[1].value_reference))
        reached = {target for target, _, _, _ in torn}
        grown = True
        while grown:
            before = len(reached)
            reached |= {link[1] for link in self.native_links if link[0] in reached}
            grown = len(reached) > before
        independent = [link for link in self.native_links if link[0] not in reached]
        dependent = [link for link in self.native_links if link[0] in reached]
        return independent + dependent, (self.loop, torn, len(independent))

    def close(self) -> None:
        """fmi2Terminate (where allowed) and fmi2FreeInstance for every instance, on every path."""
        for unit in self.units.values():
            unit.fmu.close()
