"""The compiled kernel: CVODE calls C code (``c/kernel.c``, ``c/kernel.h``) that calls the FMUs' own functions.

For each evaluation :c:func:`hs_rhs` and :c:func:`hs_root` set every FMU's time and states, copy the
continuous Real connections in the master's propagation order (algebraic loops solved by Newton, as
:class:`~heliostep.cosim.loops.LoopSolver` does) and read the derivatives or event indicators, with no
Python in between; :meth:`Kernel.advance` is the one loop over CVODE's internal steps, recording rows in
blocks. A status worse than warning stops the evaluation and is collected by :meth:`Kernel.take_error` as
the instance's :class:`~heliostep.cosim.instance.FMIError`. The ctypes Structures mirror ``kernel.h``
(checked by ``tests/cosim/test_kernel_layout.py``); the library is built at first use
(:mod:`~heliostep.cosim.libraries`).
"""

from __future__ import annotations

import ctypes
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from heliostep.cosim import sundials, watch
from heliostep.cosim.libraries import KernelBuildError, compiled_library, kernels_dir  # noqa: F401 - re-exported

if TYPE_CHECKING:
    from heliostep.cosim.instance import FMIError, ModelExchangeBase
    from heliostep.cosim.loops import LoopError, LoopSolver

#: The kernel's C source and header (package data beside this module).
SOURCE_PATH = Path(__file__).resolve().parent / "c" / "kernel.c"
HEADER_PATH = SOURCE_PATH.with_name("kernel.h")

#: The FMI function of each ``failed_function`` code of the C kernel (kernel.h: F_SET_TIME ...).
FUNCTIONS = list(watch.KERNEL_FUNCTIONS)

#: What :c:func:`hs_advance` returns (kernel.h).
ADVANCE_REACHED, ADVANCE_ROOT, ADVANCE_FULL, ADVANCE_MAX_STEPS = 0, 1, 2, 3
ADVANCE_CVODE_FAILED, ADVANCE_FMU_FAILED, ADVANCE_DKY_FAILED = -1, -2, -3

#: kernel.h: hs_kernel.status of a failed loop, and hs_loop.failure's codes.
LOOP_FAILED, LOOP_NO_CONVERGENCE, LOOP_SINGULAR = 100, 1, 2

#: kernel.h's ``prepare_t``: ``int prepare(double t, const double *x, void *user)``.
PREPARE_CALLBACK = ctypes.CFUNCTYPE(ctypes.c_int, ctypes.c_double, ctypes.c_void_p, ctypes.c_void_p)


class Outputs(ctypes.Structure):
    """kernel.h ``hs_outputs``."""

    _fields_ = [("n", ctypes.c_long), ("vrs", ctypes.c_void_p), ("columns", ctypes.c_void_p), ("ints", ctypes.c_void_p)]


class Unit(ctypes.Structure):
    """kernel.h ``hs_unit``."""

    _fields_ = (
        [("component", ctypes.c_void_p)]
        + [
            (name, ctypes.c_void_p)
            for name in (
                "set_time",
                "set_states",
                "get_derivatives",
                "get_event_indicators",
                "get_real",
                "set_real",
                "get_integer",
                "get_boolean",
            )
        ]
        + [(name, ctypes.c_long) for name in ("nx", "x_offset", "nz", "z_offset")]
        + [(name, Outputs) for name in ("real_outputs", "integer_outputs", "boolean_outputs")]
    )


class Link(ctypes.Structure):
    """kernel.h ``hs_link``."""

    _fields_ = [
        ("source", ctypes.c_long),
        ("target", ctypes.c_long),
        ("n", ctypes.c_long),
        ("source_vrs", ctypes.c_void_p),
        ("target_vrs", ctypes.c_void_p),
        ("buffer", ctypes.c_void_p),
        ("factor", ctypes.c_void_p),
        ("offset", ctypes.c_void_p),
    ]


class KernelState(ctypes.Structure):
    """kernel.h ``hs_kernel``."""

    _fields_ = [
        ("n_units", ctypes.c_long),
        ("units", ctypes.POINTER(Unit)),
        ("n_links", ctypes.c_long),
        ("links", ctypes.POINTER(Link)),
        ("data", ctypes.c_void_p),
        ("discrete", ctypes.c_long),
        ("nx", ctypes.c_long),
        ("rhs_count", ctypes.c_long),
        ("status", ctypes.c_long),
        ("failed_unit", ctypes.c_long),
        ("failed_function", ctypes.c_long),
        ("failed_time", ctypes.c_double),
        ("cvode", ctypes.c_void_p),
        ("get_dky", ctypes.c_void_p),
        ("n_inputs", ctypes.c_long),
        ("row_width", ctypes.c_long),
        ("inputs", ctypes.c_void_p),
        ("scratch", ctypes.c_void_p),
        ("pending", ctypes.c_long),
        ("step_time", ctypes.c_double),
        ("step_flag", ctypes.c_int),
        ("prepare", ctypes.c_void_p),
        ("prepare_user", ctypes.c_void_p),
        ("where", ctypes.c_void_p),
        ("loop", ctypes.c_void_p),
    ]


class LoopState(ctypes.Structure):
    """kernel.h ``hs_loop``: the torn inputs of the algebraic loops, solved in C."""

    _fields_ = (
        [("n", ctypes.c_long), ("first_link", ctypes.c_long)]
        + [
            (name, ctypes.c_void_p)
            for name in ("target_units", "source_units", "target_vrs", "source_vrs", "v", "work")
        ]
        + [("rtol", ctypes.c_double), ("atol", ctypes.c_double)]
        + [(name, ctypes.c_long) for name in ("max_iterations", "solves", "iterations", "most_iterations")]
        + [("failure", ctypes.c_long), ("failed_time", ctypes.c_double)]
    )


class AdvanceArgs(ctypes.Structure):
    """kernel.h ``hs_advance_args``: one call of :c:func:`hs_advance`."""

    _fields_ = [
        ("cvode_mem", ctypes.c_void_p),
        ("y", ctypes.c_void_p),
        ("dky", ctypes.c_void_p),
        ("t_stop", ctypes.c_double),
        ("grid", ctypes.c_void_p),
        ("n_grid", ctypes.c_long),
        ("interpolate", ctypes.c_int),
        ("rows", ctypes.c_void_p),
        ("kinds", ctypes.c_void_p),
        ("capacity", ctypes.c_long),
        ("max_steps", ctypes.c_long),
        ("max_outputs", ctypes.c_long),
        ("next_output", ctypes.c_long),
        ("n_rows", ctypes.c_long),
        ("steps", ctypes.c_long),
        ("t_reached", ctypes.c_double),
        ("cvode_flag", ctypes.c_int),
    ]


#: The ctypes mirror of each structure of kernel.h, by its C name.
STRUCTURES: dict[str, type[ctypes.Structure]] = {
    "hs_where": watch.Record,
    "hs_outputs": Outputs,
    "hs_unit": Unit,
    "hs_link": Link,
    "hs_kernel": KernelState,
    "hs_advance_args": AdvanceArgs,
    "hs_loop": LoopState,
}


def library_path() -> Path:
    """The compiled kernel, built at first use and cached by content (source, header, compiler version)."""
    return compiled_library("heliostep_kernel", "the kernel", [SOURCE_PATH, HEADER_PATH])


_library: ctypes.CDLL | None = None


def library() -> ctypes.CDLL:
    """The compiled kernel, loaded once per process."""
    global _library
    if _library is None:
        _library = ctypes.CDLL(str(library_path()))
        _library.hs_advance.argtypes = [ctypes.c_void_p, ctypes.POINTER(AdvanceArgs)]
        _library.hs_advance.restype = ctypes.c_int
        _library.hs_describe.argtypes, _library.hs_describe.restype = [ctypes.c_char_p], ctypes.c_long
    return _library


def describe(name: str) -> int:
    """What the compiled kernel says of ``name``: sizeof ``"hs_unit"``, offsetof ``"hs_unit.nx"``,
    the value of a code ``"ADVANCE_ROOT"``; -1 for a name it does not know."""
    return int(library().hs_describe(name.encode()))


#: One unit for the kernel: (instance, state offset, indicator offset, traced outputs as
#: (FMI type, value reference, column of the row)).
KernelUnit = tuple["ModelExchangeBase", int, int, Sequence[tuple[str, int, int]]]
#: One continuous Real connection group: (source unit index, target unit index, source value
#: references, target value references, per connection its (factor, offset) or None; None for none).
KernelLink = tuple[int, int, Sequence[int], Sequence[int], Sequence[tuple[float, float] | None] | None]
#: The algebraic loops for the kernel: the Python solver (its names, tolerances, iteration bound
#: and guess ``v``, shared), per torn connection (target unit index, target value reference,
#: source unit index, source value reference), and the index of the first of the kernel's links
#: that depend on the torn inputs (those from it on are copied in every Newton evaluation).
KernelLoop = tuple["LoopSolver", Sequence[tuple[int, int, int, int]], int]
#: Advance's outcome: (hs_advance's code, time reached [s], index of the next output time, CVODE's last flag).
AdvanceOutcome = tuple[int, float, int, int]


def block_bytes(row_width: int) -> int:
    """Bytes of a kernel's block of rows placed in a buffer (:attr:`Kernel.block_buffer`): the
    arguments of :c:func:`hs_advance` (their count of rows recorded), the rows' kinds, the rows."""
    return ctypes.sizeof(AdvanceArgs) + 8 * Kernel.ROWS_PER_BLOCK * (1 + row_width)


def place_block(buffer: memoryview, row_width: int) -> tuple[AdvanceArgs, np.ndarray, np.ndarray]:
    """The arguments, the kinds and the (column-major) rows of a kernel's block, in ``buffer``."""
    if len(buffer) < block_bytes(row_width):
        raise ValueError(f"a block of rows {row_width} wide needs {block_bytes(row_width)} bytes, not {len(buffer)}")
    capacity, offset = Kernel.ROWS_PER_BLOCK, ctypes.sizeof(AdvanceArgs)
    kinds = np.ndarray((capacity,), np.int64, buffer, offset)
    rows = np.ndarray((row_width, capacity), float, buffer, offset + 8 * capacity)
    return AdvanceArgs.from_buffer(buffer), kinds, rows


def rows_not_handed_over(buffer: memoryview, row_width: int) -> tuple[np.ndarray, np.ndarray]:
    """The rows (copies, one a row) and their kinds that a kernel recorded in the block in ``buffer``
    (:attr:`Kernel.block_buffer`) and did not hand over: read by another process after its death."""
    args, kinds, rows = place_block(buffer, row_width)
    n = min(max(int(args.n_rows), 0), Kernel.ROWS_PER_BLOCK)
    return rows[:, :n].T.copy(), kinds[:n].copy()


class Kernel:
    """The C structures for one run: FMU handles and function pointers, connections, error record.

    ``units`` lists the FMUs in the master's order (:data:`KernelUnit`); ``links`` the continuous
    Real connections in the master's propagation order (:data:`KernelLink`; none when the master
    propagates itself); ``inputs`` is the array the master keeps its inputs' current values in
    (columns 1.. of a row; the master changes it in place, at events only). ``prepare``, when
    given, replaces the kernel's own preparation of the FMUs for a row of :meth:`advance`
    (kernel.h ``prepare_t``: ``prepare(t, x)`` with ``x`` the address of the states, None without
    states; returns 0, or -1 once it has recorded its error; it must not raise).
    """

    #: Rows one call of :c:func:`hs_advance` records before it hands them over.
    ROWS_PER_BLOCK = 4096
    #: Rows at output times (the trace's) one call records before it hands them over: fewer in a
    #: supervised child (:data:`heliostep.run.supervision.child.BLOCK_ROWS`), which streams them as it goes.
    OUTPUTS_PER_BLOCK = 4096
    #: Where the next kernels keep their block of rows and its count (:func:`place_block`): a writable
    #: buffer of :func:`block_bytes` bytes that another process can read after this one died (a
    #: supervised child's, :mod:`heliostep.run.supervision.journal`), or None for memory of their own.
    block_buffer: memoryview | None = None

    def __init__(
        self,
        units: Sequence[KernelUnit],
        links: Sequence[KernelLink],
        n_states: int,
        inputs: np.ndarray | None = None,
        row_width: int = 1,
        prepare: Callable[[float, int | None], int] | None = None,
        loop: KernelLoop | None = None,
    ):
        self.instances = [fmu for fmu, _, _, _ in units]
        self._keep: list[Any] = []  # arrays whose addresses the C structures hold
        self._units = (Unit * max(1, len(units)))()
        for k, unit in enumerate(units):
            self._fill_unit(self._units[k], *unit)
        self._links = self._fill_links(links)
        self.state = KernelState()
        self.state.n_units, self.state.units = len(units), self._units
        self.state.n_links, self.state.links = len(links), self._links
        self.state.data = sundials.vector_data_address()
        self.state.discrete = int(n_states == 0)
        self.state.nx = max(1, n_states)
        self.state.cvode = sundials.cvode_address("CVode")
        self.state.get_dky = sundials.cvode_address("CVodeGetDky")
        self.inputs = np.zeros(0) if inputs is None else inputs
        self.state.n_inputs, self.state.inputs = len(self.inputs), self.inputs.ctypes.data
        self.state.row_width = row_width
        self._scratch = np.zeros(max([1] + [len(outputs) for _, _, _, outputs in units]))
        self.state.scratch = self._scratch.ctypes.data
        self.state.where = watch.record_address()  # a supervisor's record of the FMI calls (or NULL)
        self._prepare = None
        if prepare is not None:  # kept: the C code holds its address
            self._prepare = PREPARE_CALLBACK(lambda t, x, user: prepare(t, x))
            self.state.prepare = ctypes.cast(self._prepare, ctypes.c_void_p).value
        self.loop_solver = None if loop is None else loop[0]
        self.loop_state = LoopState()
        if loop is not None:
            self._fill_loop(*loop)
        if Kernel.block_buffer is None:
            self.args = AdvanceArgs()
            self.rows = np.zeros((row_width, self.ROWS_PER_BLOCK))  # column-major (kernel.h): its transpose the rows
            self.kinds = np.zeros(self.ROWS_PER_BLOCK, dtype=np.int64)
        else:
            self.args, self.kinds, self.rows = place_block(Kernel.block_buffer, row_width)
        self.user_data = ctypes.cast(ctypes.pointer(self.state), ctypes.c_void_p)
        self._library = library()
        self.rhs = sundials.function_address(self._library, "hs_rhs")
        self.root = sundials.function_address(self._library, "hs_root")

    def _fill_links(self, links: Sequence[KernelLink]) -> Any:
        """kernel.h ``hs_link`` of each link, its arrays kept alive in ``_keep``."""
        filled = (Link * max(1, len(links)))()
        for k, (source, target, source_vrs, target_vrs, transforms) in enumerate(links):
            arrays: tuple[np.ndarray, ...] = (
                np.array(source_vrs, dtype=np.uint32),
                np.array(target_vrs, dtype=np.uint32),
                np.zeros(len(source_vrs)),
            )
            link = filled[k]
            link.source, link.target, link.n = source, target, len(source_vrs)
            link.source_vrs, link.target_vrs, link.buffer = (a.ctypes.data for a in arrays)
            if transforms is not None:  # per value (factor, offset); NULL: copied as they are
                scale = np.array([t if t is not None else (1.0, 0.0) for t in transforms], dtype=float).T.copy()
                arrays += (scale,)
                link.factor, link.offset = scale[0].ctypes.data, scale[1].ctypes.data
            self._keep.append(arrays)
        return filled

    def _fill_loop(self, solver: LoopSolver, torn: Sequence[tuple[int, int, int, int]], first_link: int) -> None:
        """The C loop solver's structure: its torn connections, and the Python solver's guess and settings."""
        n = len(torn)
        arrays = (
            np.array([c[0] for c in torn], dtype=np.int64),
            np.array([c[2] for c in torn], dtype=np.int64),
            np.array([c[1] for c in torn], dtype=np.uint32),
            np.array([c[3] for c in torn], dtype=np.uint32),
            np.zeros(n * n + 4 * n),  # kernel.h hs_loop.work: v, r, two more vectors, the Jacobian
        )
        self._keep.append(arrays)
        self._loop_work = arrays[4]  # after a solve that failed: its last iterate and residual
        state = self.loop_state
        state.n, state.first_link = n, first_link
        state.target_units, state.source_units, state.target_vrs, state.source_vrs, state.work = (
            a.ctypes.data for a in arrays
        )
        state.v = solver.v.ctypes.data  # shared: each solver starts from the other's last solution
        state.rtol, state.atol, state.max_iterations = solver.rtol, solver.atol, solver.max_iterations
        self.state.loop = ctypes.cast(ctypes.pointer(state), ctypes.c_void_p).value

    def loop_counts(self) -> tuple[int, int, int]:
        """The C loop solver's solves, Newton iterations and most iterations in one solve."""
        state = self.loop_state
        return int(state.solves), int(state.iterations), int(state.most_iterations)

    def _fill_unit(
        self, u: Unit, fmu: ModelExchangeBase, x_offset: int, z_offset: int, outputs: Sequence[tuple[str, int, int]]
    ) -> None:
        u.component = fmu.component
        for field, function in (
            ("set_time", "fmi2SetTime"),
            ("set_states", "fmi2SetContinuousStates"),
            ("get_derivatives", "fmi2GetDerivatives"),
            ("get_event_indicators", "fmi2GetEventIndicators"),
            ("get_real", "fmi2GetReal"),
            ("set_real", "fmi2SetReal"),
            ("get_integer", "fmi2GetInteger"),
            ("get_boolean", "fmi2GetBoolean"),
        ):
            setattr(u, field, fmu.function_address(function))
        u.nx, u.x_offset, u.nz, u.z_offset = fmu.n_states, x_offset, fmu.n_event_indicators, z_offset
        for field, kinds in (
            ("real_outputs", ("Real",)),
            ("integer_outputs", ("Integer", "Enumeration")),
            ("boolean_outputs", ("Boolean",)),
        ):
            chosen = [(vr, column) for kind, vr, column in outputs if kind in kinds]
            arrays = (
                np.array([vr for vr, _ in chosen], dtype=np.uint32),
                np.array([column for _, column in chosen], dtype=np.int64),
                np.zeros(len(chosen), dtype=np.int32),
            )
            self._keep.append(arrays)
            group = getattr(u, field)
            group.n = len(chosen)
            group.vrs, group.columns = arrays[0].ctypes.data, arrays[1].ctypes.data
            group.ints = arrays[2].ctypes.data if field != "real_outputs" else None

    def advance(
        self,
        cvode_mem: int,
        y: int,
        dky: int,
        t_stop: float,
        grid: np.ndarray,
        next_output: int,
        interpolate: bool,
        max_steps: int,
        take_rows: Callable[[np.ndarray, np.ndarray], None],
    ) -> AdvanceOutcome:
        """CVODE (its stop time set to ``t_stop``) in one-step mode up to ``t_stop`` or the first root,
        the loop over internal steps in C (:c:func:`hs_advance`).

        Rows (time, master inputs, traced outputs) are recorded after each internal step but the
        last (kind 0) and, with ``interpolate``, at the output times ``grid[next_output:]`` passed
        on the way, from CVODE's interpolating polynomial (kind 1); ``take_rows(rows, kinds)`` gets
        them in blocks, in time order (views valid during the call only, each column contiguous; it may
        raise to stop).
        Returns hs_advance's last code (never ADVANCE_FULL), the time reached, the index of the
        next output time and CVODE's last flag; on ADVANCE_REACHED and ADVANCE_ROOT the FMUs hold
        the solution at the time reached. When an FMU fails, its error stays recorded for
        :meth:`take_error`.
        """
        grid = np.ascontiguousarray(grid, dtype=float)
        args = self.args
        args.cvode_mem, args.y, args.dky, args.t_stop = cvode_mem, y, dky, t_stop
        args.grid, args.n_grid, args.interpolate = grid.ctypes.data, len(grid), int(interpolate)
        args.rows, args.kinds, args.capacity = self.rows.ctypes.data, self.kinds.ctypes.data, self.ROWS_PER_BLOCK
        args.max_steps, args.max_outputs = max_steps, max(1, self.OUTPUTS_PER_BLOCK)
        args.next_output, args.steps, args.t_reached, args.cvode_flag = next_output, 0, np.nan, 0
        while True:
            args.n_rows = 0
            status = self._library.hs_advance(self.user_data, ctypes.byref(args))
            for fmu in self.instances:
                fmu.time = args.t_reached
            try:
                if args.n_rows:
                    take_rows(self.rows[:, : args.n_rows].T, self.kinds[: args.n_rows])
            finally:
                args.n_rows = 0  # handed over: what the block holds now is none of them
            if status != ADVANCE_FULL:
                return status, float(args.t_reached), int(args.next_output), int(args.cvode_flag)

    @property
    def rhs_count(self) -> int:
        """Right-hand-side evaluations of :c:func:`hs_rhs` so far."""
        return int(self.state.rhs_count)

    def take_error(self) -> tuple[FMIError | LoopError, float] | None:
        """The FMIError of a failed evaluation (the FMU's messages, the true time) or the LoopError
        of a loop that failed, and that time, or None; clears it."""
        if not self.state.status:
            return None
        if self.state.status == LOOP_FAILED and self.loop_solver is not None:
            loop, self.state.status = self.loop_state, 0
            time = float(loop.failed_time)
            if loop.failure == LOOP_SINGULAR:
                return self.loop_solver.breakdown(time), time
            n, work = int(loop.n), self._loop_work
            return self.loop_solver.no_convergence(time, work[:n].copy(), work[n : 2 * n].copy()), time
        fmu = self.instances[self.state.failed_unit]
        time = float(self.state.failed_time)
        fmu.time = time
        error = fmu.status_error(
            watch.called_function(self.state.failed_function, fmu.info.kind), int(self.state.status)
        )
        self.state.status = 0
        return error, time
