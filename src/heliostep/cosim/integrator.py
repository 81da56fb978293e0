"""The integrator: one CVODE (BDF, Newton, dense linear solver, root finding) over the coupled states.

:class:`Integrator` is the protocol the master drives; its call order, for one run:

1. construct it once the FMUs are initialized and the first event iteration is done (it reads
   the states and their nominals from the coupled system, ``get_x``/``get_nominals``);
2. :meth:`~Integrator.step` (CVODE in normal mode, without a monitor) or
   :meth:`~Integrator.advance` (one-step mode with rows recorded on the way, with a monitor) up
   to the next stop; after either the FMUs hold the solution at the time reached;
3. after an event at ``t``: :meth:`~Integrator.reset` (re-reads the states and nominals and
   restarts CVODE), then 2. again;
4. whenever 2. or 3. raised: :meth:`~Integrator.take_error` gives the error raised inside one of
   CVODE's callbacks with the time of the failing evaluation (the cause to report, rather than
   CVODE's generic failure), or None;
5. :meth:`~Integrator.close`.

Its two implementations differ in the right-hand side and root function CVODE calls:
:class:`CompiledIntegrator` gives CVODE the compiled kernel's ``hs_rhs``/``hs_root``
(:mod:`heliostep.cosim.kernel`); :class:`CallbackIntegrator` gives it ctypes callbacks into the
coupled system's Python methods (for non-Real continuous connections, or torn connections the kernel
cannot take; algebraic loops of Real connections are solved in the kernel): :func:`make_integrator`
chooses by the system, and the run's statistics say which (``compiled_rhs``).
Both run the one loop over CVODE's internal steps, the kernel's ``hs_advance``
(:meth:`heliostep.cosim.kernel.Kernel.advance`): with the Python callbacks the
kernel is handed the coupled system's own preparation of the FMUs for each row.
"""

from __future__ import annotations

import ctypes
from collections.abc import Callable
from typing import Any, Protocol

import numpy as np

from heliostep.cosim import sundials
from heliostep.cosim.kernel import (
    ADVANCE_DKY_FAILED,
    ADVANCE_FMU_FAILED,
    ADVANCE_MAX_STEPS,
    ADVANCE_REACHED,
    ADVANCE_ROOT,
    Kernel,
)
from heliostep.cosim.signals import SolverOptions, cvode_failure, too_many_steps
from heliostep.cosim.system import CoupledSystem


class Integrator(Protocol):
    """What the master uses of an integrator (call order: see the module's docstring)."""

    #: True when CVODE calls the compiled right-hand side.
    compiled: bool

    def step(self, t_next: float) -> tuple[bool, float]:
        """CVODE in normal mode to ``t_next`` or the first root: (root found, time reached [s])."""
        ...

    def advance(
        self,
        t_stop: float,
        grid: np.ndarray,
        next_output: int,
        interpolate: bool,
        take_rows: Callable[[np.ndarray, np.ndarray], None],
    ) -> tuple[bool, float, int]:
        """One-step mode to ``t_stop`` or the first root, rows to ``take_rows`` on the way:
        (root found, time reached [s], index of the next output time of ``grid``)."""
        ...

    def reset(self, t: float) -> None:
        """Restart at ``t`` [s] from the FMUs' states (after an event)."""
        ...

    def take_error(self) -> tuple[BaseException, float] | None:
        """The error raised inside a callback and the time [s] of that evaluation, or None; clears it."""
        ...

    def rhs_evaluations(self) -> int:
        """Right-hand-side evaluations the integrator counted itself (the compiled one; 0 else)."""
        ...

    def close(self) -> None:
        """Free CVODE's memory (safe to call twice)."""
        ...


class StateAccess(Protocol):
    """What an integrator needs of the coupled system: its states and nominals at addresses of doubles."""

    def get_x(self, address: int) -> None: ...

    def set_x(self, address: int) -> None: ...

    def get_nominals(self, address: int, n: int) -> None: ...


class CallbackSystem(StateAccess, Protocol):
    """What the Python callbacks need of the coupled system besides its states."""

    def set_time(self, t: float) -> None: ...

    def get_dx(self, address: int) -> None: ...

    def get_z(self, address: int) -> None: ...


class CallbackErrors:
    """The first exception raised inside a callback of CVODE or of the kernel, kept with its time.

    A callback must not raise into C: :meth:`guard` runs it, keeps the first exception and
    returns -1 (CVODE's "unrecoverable"); every later guarded call returns -1 at once.
    """

    def __init__(self) -> None:
        self.error: BaseException | None = None
        self.time = float("nan")

    def guard(self, method: Callable[..., Any], t: float, *args: Any) -> int:
        if self.error is not None:
            return -1
        try:
            method(t, *args)
        except BaseException as exc:  # noqa: BLE001 - kept and re-raised outside the callback
            self.error, self.time = exc, float(t)
            return -1
        return 0

    def take(self) -> tuple[BaseException, float] | None:
        if self.error is None:
            return None
        error, self.error = self.error, None
        return error, self.time


class CVodeIntegrator:
    """CVODE on a right-hand side and a root function given as C function addresses.

    ``rhs``/``root`` are called by CVODE with ``user_data``; ``kernel`` runs the one-step loop of
    :meth:`advance` (None: only :meth:`step` is available); ``errors`` keeps what the
    callbacks raised (Python callbacks; None for the compiled kernel, which records its own).
    """

    compiled = False

    def __init__(
        self,
        states: StateAccess,
        rhs: int,
        root: int,
        user_data: int | None,
        nx: int,
        nz: int,
        start_time: float,
        options: SolverOptions,
        kernel: Kernel | None,
        errors: CallbackErrors | None = None,
    ):
        self.states, self.kernel, self.errors = states, kernel, errors
        self.max_num_steps = options.max_num_steps
        self.error_info: tuple | None = None
        self.reltol = options.rtol
        self.discrete = nx == 0
        self.idle = self.discrete and nz == 0  # nothing to integrate, no root to find: CVode(t) would say t
        self.nx = 1 if self.discrete else nx
        self.nz = nz
        self.cvode_mem: int | None = None
        self._reached = ctypes.c_double(0.0)  # where CVode's call got to, a buffer kept for every call
        self._reached_at = ctypes.byref(self._reached)
        self._create(rhs, root, user_data, start_time, options)

    def _create(self, rhs: int, root: int, user_data: int | None, start_time: float, options: SolverOptions) -> None:
        context = ctypes.c_void_p()
        self._check(sundials.SUNContext_Create(sundials.SUN_COMM_NULL, ctypes.byref(context)), "SUNContext_Create")
        self.sunctx = context.value
        self.x = sundials.N_VNew_Serial(self.nx, self.sunctx)
        self.abstol = sundials.N_VNew_Serial(self.nx, self.sunctx)
        self.dky = sundials.N_VNew_Serial(self.nx, self.sunctx)  # interpolated states (Kernel.advance)
        self.px = sundials.N_VGetArrayPointer(self.x)
        self.pabstol = sundials.N_VGetArrayPointer(self.abstol)
        self.npabstol = np.ctypeslib.as_array(ctypes.cast(self.pabstol, ctypes.POINTER(ctypes.c_double)), (self.nx,))
        if self.discrete:
            np.ctypeslib.as_array(ctypes.cast(self.px, ctypes.POINTER(ctypes.c_double)), (self.nx,))[:] = 1.0
            self.npabstol[:] = 1.0
        else:
            self.states.get_x(self.px)
            self.states.get_nominals(self.pabstol, self.nx)
        self.npabstol *= self.reltol
        self.cvode_mem = sundials.CVodeCreate(sundials.CV_BDF, self.sunctx)
        mem = self.cvode_mem
        self._check(sundials.CVodeInit(mem, rhs, start_time, self.x), "CVodeInit")
        if user_data is not None:
            self._check(sundials.CVodeSetUserData(mem, user_data), "CVodeSetUserData")
        self._check(sundials.CVodeSVtolerances(mem, options.rtol, self.abstol), "CVodeSVtolerances")
        self._check(sundials.CVodeRootInit(mem, self.nz, root), "CVodeRootInit")
        self.A = sundials.SUNDenseMatrix(self.nx, self.nx, self.sunctx)
        self.LS = sundials.SUNLinSol_Dense(self.x, self.A, self.sunctx)
        self._check(sundials.CVodeSetLinearSolver(mem, self.LS, self.A), "CVodeSetLinearSolver")
        self._check(sundials.CVodeSetMaxStep(mem, options.max_step), "CVodeSetMaxStep")
        self._check(sundials.CVodeSetMaxNumSteps(mem, options.max_num_steps), "CVodeSetMaxNumSteps")
        self._check(sundials.CVodeSetNoInactiveRootWarn(mem), "CVodeSetNoInactiveRootWarn")
        self._error_handler = sundials.ERROR_HANDLER(self._record_error)
        # ours alone: SUNDIALS' default handler would also print every failure to stderr ("[ERROR]...
        # mxstep steps taken"), even one the caller expects and handles (a holding test's runaway rotor);
        # the message reaches the user in the error raised from it (cvode_failure)
        self._check(sundials.SUNContext_ClearErrHandlers(self.sunctx), "SUNContext_ClearErrHandlers")
        self._check(
            sundials.SUNContext_PushErrHandler(self.sunctx, self._error_handler, None), "SUNContext_PushErrHandler"
        )

    @staticmethod
    def _check(flag: int, what: str) -> None:
        if flag != 0:
            raise RuntimeError(f"{what} failed (flag {flag})")

    def _record_error(
        self, line: int, func: bytes, file: bytes, msg: bytes, err_code: int, err_user_data: Any, sunctx: Any
    ) -> None:
        self.error_info = (err_code, func.decode("utf-8"), file.decode("utf-8"), msg.decode("utf-8"))

    # ------------------------------------------------------------------ the protocol
    def step(self, t_next: float) -> tuple[bool, float]:
        if self.idle:  # (a system of sampled components only, say: CVODE's one-state stand-in is not stepped)
            return False, float(t_next)
        if not self.discrete:
            self.states.get_x(self.px)
        reached = self._reached
        flag = sundials.CVode(self.cvode_mem, t_next, self.x, self._reached_at, sundials.CV_NORMAL)
        if flag < 0:  # (the FMUs are not touched: an FMU in its error state keeps its messages)
            raise cvode_failure(self.error_info, flag)
        if not self.discrete:
            self.states.set_x(self.px)
        return flag > 0, reached.value

    def advance(
        self,
        t_stop: float,
        grid: np.ndarray,
        next_output: int,
        interpolate: bool,
        take_rows: Callable[[np.ndarray, np.ndarray], None],
    ) -> tuple[bool, float, int]:
        if self.kernel is None or self.cvode_mem is None:
            raise RuntimeError("this integrator has no kernel for the one-step loop, or is closed")
        if not self.discrete:
            self.states.get_x(self.px)
        if sundials.CVodeSetStopTime(self.cvode_mem, t_stop) < 0:
            raise RuntimeError(f"CVodeSetStopTime({t_stop}) failed")
        status, reached, next_output, flag = self.kernel.advance(
            self.cvode_mem, self.x, self.dky, t_stop, grid, next_output, interpolate, self.max_num_steps, take_rows
        )
        if status in (ADVANCE_REACHED, ADVANCE_ROOT):
            if not self.discrete:
                self.states.set_x(self.px)
            return status == ADVANCE_ROOT, reached, next_output
        if status == ADVANCE_FMU_FAILED:  # the error stays recorded for take_error
            raise RuntimeError("an FMU failed inside the compiled one-step loop")
        if status == ADVANCE_MAX_STEPS:
            raise too_many_steps(self.max_num_steps, t_stop, reached)
        if status == ADVANCE_DKY_FAILED:
            raise RuntimeError(f"CVodeGetDky failed between t = {reached:.9g} s and the step before")
        raise cvode_failure(self.error_info, flag)

    def reset(self, t: float) -> None:
        if not self.discrete:
            self.states.get_x(self.px)
            self.states.get_nominals(self.pabstol, self.nx)
            self.npabstol *= self.reltol
        self._check(sundials.CVodeReInit(self.cvode_mem, t, self.x), "CVodeReInit")

    def take_error(self) -> tuple[BaseException, float] | None:
        taken = self.errors.take() if self.errors is not None else None
        if taken is None and self.kernel is not None:
            taken = self.kernel.take_error()
        return taken

    def rhs_evaluations(self) -> int:
        return 0

    def close(self) -> None:
        if self.cvode_mem:
            sundials.CVodeFree(ctypes.byref(ctypes.c_void_p(self.cvode_mem)))
            self.cvode_mem = None

    def __del__(self) -> None:
        self.close()


class CompiledIntegrator(CVodeIntegrator):
    """CVODE calling the compiled kernel's ``hs_rhs`` and ``hs_root`` (no Python per evaluation)."""

    compiled = True

    def __init__(
        self, states: StateAccess, kernel: Kernel, nx: int, nz: int, start_time: float, options: SolverOptions
    ):
        super().__init__(states, kernel.rhs, kernel.root, kernel.user_data.value, nx, nz, start_time, options, kernel)

    def rhs_evaluations(self) -> int:
        assert self.kernel is not None
        return self.kernel.rhs_count


class CallbackIntegrator(CVodeIntegrator):
    """CVODE calling ctypes callbacks into the coupled system: per evaluation set the time and the
    states, then read the derivatives (``get_dx``) or the event indicators (``get_z``), as fmpy's
    ``CVodeSolver`` does. What a callback raises is kept in ``errors`` (:meth:`take_error`)."""

    def __init__(
        self,
        system: CallbackSystem,
        nx: int,
        nz: int,
        start_time: float,
        options: SolverOptions,
        kernel: Kernel | None,
        errors: CallbackErrors,
    ):
        self.system = system
        self._rhs = sundials.RHS_CALLBACK(lambda t, y, ydot, user: errors.guard(self._f, t, y, ydot))
        self._root = sundials.ROOT_CALLBACK(lambda t, y, gout, user: errors.guard(self._g, t, y, gout))
        super().__init__(
            system, _address(self._rhs), _address(self._root), None, nx, nz, start_time, options, kernel, errors
        )

    def _f(self, t: float, y: int, ydot: int) -> None:
        self.system.set_time(t)
        if self.discrete:
            np.ctypeslib.as_array(_doubles(sundials.N_VGetArrayPointer(ydot)), (self.nx,))[:] = 0.0
        else:
            self.system.set_x(sundials.N_VGetArrayPointer(y))
            self.system.get_dx(sundials.N_VGetArrayPointer(ydot))

    def _g(self, t: float, y: int, gout: int) -> None:
        self.system.set_time(t)
        if not self.discrete:
            self.system.set_x(sundials.N_VGetArrayPointer(y))
        self.system.get_z(gout)


def _address(function: Any) -> int:
    return ctypes.cast(function, ctypes.c_void_p).value or 0


def _doubles(address: int) -> Any:
    return ctypes.cast(address, ctypes.POINTER(ctypes.c_double))


def make_integrator(
    system: CoupledSystem,
    start_time: float,
    options: SolverOptions,
    input_values: np.ndarray,
    row_width: int,
    monitored: bool,
) -> Integrator:
    """CVODE on the compiled kernel where the system allows it (:func:`compiled_kernel`), else on the
    Python callbacks; the kernel's one-step loop in both cases when the run is ``monitored``. The
    kernel reads the master's inputs from ``input_values`` (updated in place) and records rows of
    ``row_width`` values."""
    nx, nz = system.n_states, system.n_indicators
    kernel = compiled_kernel(system, input_values, row_width)
    if kernel is not None:
        return CompiledIntegrator(system, kernel, nx, nz, start_time, options)
    errors = CallbackErrors()
    native = None
    if monitored:
        native = Kernel(
            system.kernel_units(),
            [],
            nx,
            inputs=input_values,
            row_width=row_width,
            prepare=lambda t, x: errors.guard(system.prepare_row, t, x),
        )
    return CallbackIntegrator(system, nx, nz, start_time, options, native, errors)


def compiled_kernel(system: CoupledSystem, input_values: np.ndarray, row_width: int) -> Kernel | None:
    """The kernel that evaluates ``system``'s right-hand side in C, its algebraic loops included, or
    None where the system needs the Python callbacks (non-Real continuous or torn connections the
    kernel cannot take)."""
    looped = system.kernel_loop()  # the links reordered for the loops, and the loops; None without
    if (system.loop is not None and looped is None) or system.native_links is None:
        return None
    links, loop = looped if looped is not None else (system.native_links, None)
    kernel = Kernel(system.kernel_units(), links, system.n_states, inputs=input_values, row_width=row_width, loop=loop)
    if system.loop is not None:  # the loops solved in C too: their counts in the run's statistics
        system.loop.compiled_counts = kernel.loop_counts
    return kernel
