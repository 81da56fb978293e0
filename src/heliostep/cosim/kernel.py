"""The compiled right-hand side: CVODE calls C code that calls the FMUs' own ``fmi2*`` functions.

For every evaluation the C functions below set the time and the states of every FMU, copy the
continuous-time Real connections in the master's propagation order (``fmi2GetReal`` then
``fmi2SetReal``) and read the derivatives (:c:func:`hs_rhs`) or the event indicators
(:c:func:`hs_root`), with no Python in between. The FMI function pointers are taken from the
FMUs' loaded libraries with ctypes and handed to the C code as addresses, together with the
``fmi2Component`` handles, so the kernel serves any set of Model Exchange FMUs the master accepts.

An FMI status worse than ``fmi2Warning`` stops the evaluation: the kernel records the status, the
instance, the function and the time of the failing evaluation, returns -1 (unrecoverable) to
CVODE, and refuses every further evaluation until the master has collected the error
(:meth:`Kernel.take_error`) and turned it into the same :class:`~heliostep.cosim.fmi.FMIError`
as the Python path.

:meth:`Kernel.advance` runs CVODE in one-step mode with the loop over internal steps in C
(:c:func:`hs_advance`): after each internal step, and at the output times passed on the way
(interpolated), it records a row (time, master inputs, every FMU's traced outputs) into a buffer
the master takes in blocks, so no Python runs per internal step either.

The C source (``c/kernel.c``) is compiled with the system C compiler (``$CC`` or ``cc``) at first use into a
cache folder beside the FMU cache (``kernels/``), under a name derived from the SHA-256 of the
source and the compiler's version: a changed source or compiler gives a new library.

:class:`NativeSolver` builds the CVODE memory itself (BDF, Newton with a dense linear solver,
root finding) with fmpy's SUNDIALS bindings and the kernel's native functions, and offers the
interface the master uses from fmpy's ``CVodeSolver`` (``step``, ``reset``, ``x``, ``px`` ...).
"""

from __future__ import annotations

import ctypes
import hashlib
import os
import shutil
import subprocess
import tempfile
from collections.abc import Callable
from pathlib import Path

import numpy as np

from heliostep.cosim.signals import cvode_failure, too_many_steps
from heliostep.errors import HeliostepError
from heliostep.paths import fmus_dir
from heliostep.toolchain import compiler_version, exclusive_lock

#: The kernel's C source (package data beside this module).
SOURCE_PATH = Path(__file__).resolve().parent / "c" / "kernel.c"

#: The FMI function of each ``failed_function`` code of the C kernel.
FUNCTIONS = ["fmi2SetTime", "fmi2SetContinuousStates", "fmi2GetReal", "fmi2SetReal", "fmi2GetDerivatives",
             "fmi2GetEventIndicators", "fmi2GetInteger", "fmi2GetBoolean"]

#: What :c:func:`hs_advance` returns.
ADVANCE_REACHED, ADVANCE_ROOT, ADVANCE_FULL, ADVANCE_MAX_STEPS = 0, 1, 2, 3
ADVANCE_CVODE_FAILED, ADVANCE_FMU_FAILED, ADVANCE_DKY_FAILED = -1, -2, -3


class _Outputs(ctypes.Structure):
    _fields_ = [("n", ctypes.c_long), ("vrs", ctypes.c_void_p), ("columns", ctypes.c_void_p),
                ("ints", ctypes.c_void_p)]


class _Unit(ctypes.Structure):
    _fields_ = [("component", ctypes.c_void_p)] + [
        (name, ctypes.c_void_p) for name in ("set_time", "set_states", "get_derivatives", "get_event_indicators",
                                             "get_real", "set_real", "get_integer", "get_boolean")] + [
        (name, ctypes.c_long) for name in ("nx", "x_offset", "nz", "z_offset")] + [
        (name, _Outputs) for name in ("real_outputs", "integer_outputs", "boolean_outputs")]


class _Link(ctypes.Structure):
    _fields_ = [("source", ctypes.c_long), ("target", ctypes.c_long), ("n", ctypes.c_long),
                ("source_vrs", ctypes.c_void_p), ("target_vrs", ctypes.c_void_p), ("buffer", ctypes.c_void_p)]


class _Kernel(ctypes.Structure):
    _fields_ = [("n_units", ctypes.c_long), ("units", ctypes.POINTER(_Unit)), ("n_links", ctypes.c_long),
                ("links", ctypes.POINTER(_Link)), ("data", ctypes.c_void_p), ("discrete", ctypes.c_long),
                ("nx", ctypes.c_long), ("rhs_count", ctypes.c_long), ("status", ctypes.c_long),
                ("failed_unit", ctypes.c_long), ("failed_function", ctypes.c_long),
                ("failed_time", ctypes.c_double),
                ("cvode", ctypes.c_void_p), ("get_dky", ctypes.c_void_p), ("n_inputs", ctypes.c_long),
                ("row_width", ctypes.c_long), ("inputs", ctypes.c_void_p), ("scratch", ctypes.c_void_p),
                ("pending", ctypes.c_long), ("step_time", ctypes.c_double), ("step_flag", ctypes.c_int)]


class KernelBuildError(HeliostepError):
    """The C compiler could not build the kernel."""


def kernels_dir() -> Path:
    """The cache of compiled kernels: beside the FMU cache."""
    return fmus_dir().parent / "kernels"


def _compiler() -> str:
    return os.environ.get("CC") or shutil.which("cc") or shutil.which("gcc") or "cc"


def library_path() -> Path:
    """The compiled kernel, built at first use and cached by content (source + compiler version)."""
    cc = _compiler()
    try:
        version = compiler_version(cc)
    except OSError as exc:
        raise KernelBuildError(f"no C compiler for the compiled kernel ({cc}): {exc}") from None
    source_text = SOURCE_PATH.read_bytes()
    digest = hashlib.sha256(source_text + b"\0" + version.encode()).hexdigest()[:24]
    folder = kernels_dir()
    path = folder / f"heliostep_kernel_{digest}.so"
    if path.exists():
        return path
    with exclusive_lock(folder / ".lock"):
        if path.exists():
            return path
        with tempfile.TemporaryDirectory(dir=folder) as work:
            source = Path(work) / "kernel.c"
            source.write_bytes(source_text)
            target = Path(work) / path.name
            result = subprocess.run([cc, "-O2", "-Wall", "-Wextra", "-Werror", "-shared", "-fPIC", "-o", str(target),
                                     str(source), "-lm"],
                                    capture_output=True, text=True)
            if result.returncode != 0:
                raise KernelBuildError(f"compiling the kernel failed:\n{result.stderr}")
            os.replace(target, path)  # atomic: other processes see no half-written library
    return path


_library = None


def library() -> ctypes.CDLL:
    global _library
    if _library is None:
        _library = ctypes.CDLL(str(library_path()))
    return _library


def _function_address(dll, name: str) -> int:
    return ctypes.cast(getattr(dll, name), ctypes.c_void_p).value


class Kernel:
    """The C structures for one run: FMU handles and function pointers, connections, error record.

    ``units`` is a list of (ModelExchangeInstance, state offset, indicator offset, outputs) in the
    master's order, ``outputs`` being the unit's traced outputs as (FMI type, value reference,
    column of the row); ``links`` a list of (source index, target index, source value
    references, target value references) of the continuous Real connections in the master's
    propagation order; ``inputs`` the array the master keeps its inputs' current values in
    (columns 1.. of a row; the master changes it in place, at events only).
    """

    #: Rows one call of :c:func:`hs_advance` records before it hands them over.
    ROWS_PER_BLOCK = 4096

    def __init__(self, units, links, n_states: int, inputs: np.ndarray | None = None, row_width: int = 1):
        from fmpy.sundials.cvode import sundials_cvode
        from fmpy.sundials.libraries import sundials_nvecserial

        self.instances = [fmu for fmu, _, _, _ in units]
        self._keep = []
        self._units = (_Unit * max(1, len(units)))()
        for k, (fmu, x_offset, z_offset, outputs) in enumerate(units):
            dll = fmu._model.dll
            u = self._units[k]
            u.component = fmu._component
            for field, function in (("set_time", "fmi2SetTime"), ("set_states", "fmi2SetContinuousStates"),
                                    ("get_derivatives", "fmi2GetDerivatives"),
                                    ("get_event_indicators", "fmi2GetEventIndicators"), ("get_real", "fmi2GetReal"),
                                    ("set_real", "fmi2SetReal"), ("get_integer", "fmi2GetInteger"),
                                    ("get_boolean", "fmi2GetBoolean")):
                setattr(u, field, _function_address(dll, function))
            u.nx, u.x_offset, u.nz, u.z_offset = fmu.n_states, x_offset, fmu.n_event_indicators, z_offset
            for field, kinds in (("real_outputs", ("Real",)), ("integer_outputs", ("Integer", "Enumeration")),
                                 ("boolean_outputs", ("Boolean",))):
                chosen = [(vr, column) for kind, vr, column in outputs if kind in kinds]
                arrays = (np.array([vr for vr, _ in chosen], dtype=np.uint32),
                          np.array([column for _, column in chosen], dtype=np.int64),
                          np.zeros(len(chosen), dtype=np.int32))
                self._keep.append(arrays)
                group = getattr(u, field)
                group.n = len(chosen)
                group.vrs, group.columns = arrays[0].ctypes.data, arrays[1].ctypes.data
                group.ints = arrays[2].ctypes.data if field != "real_outputs" else None
        self._links = (_Link * max(1, len(links)))()
        for k, (source, target, source_vrs, target_vrs) in enumerate(links):
            arrays = (np.array(source_vrs, dtype=np.uint32), np.array(target_vrs, dtype=np.uint32),
                      np.zeros(len(source_vrs)))
            self._keep.append(arrays)
            link = self._links[k]
            link.source, link.target, link.n = source, target, len(source_vrs)
            link.source_vrs, link.target_vrs, link.buffer = (a.ctypes.data for a in arrays)
        self.state = _Kernel()
        self.state.n_units, self.state.units = len(units), self._units
        self.state.n_links, self.state.links = len(links), self._links
        self.state.data = _function_address(sundials_nvecserial, "N_VGetArrayPointer")
        self.state.discrete = int(n_states == 0)
        self.state.nx = max(1, n_states)
        self.state.cvode = _function_address(sundials_cvode, "CVode")
        self.state.get_dky = _function_address(sundials_cvode, "CVodeGetDky")
        self.inputs = np.zeros(0) if inputs is None else inputs
        self.state.n_inputs, self.state.inputs = len(self.inputs), self.inputs.ctypes.data
        self.state.row_width = row_width
        self._scratch = np.zeros(max([1] + [len(outputs) for _, _, _, outputs in units]))
        self.state.scratch = self._scratch.ctypes.data
        self.rows = np.zeros((self.ROWS_PER_BLOCK, row_width))
        self.kinds = np.zeros(self.ROWS_PER_BLOCK, dtype=np.int64)
        self.user_data = ctypes.cast(ctypes.pointer(self.state), ctypes.c_void_p)
        dll = library()
        self.rhs = _function_address(dll, "hs_rhs")
        self.root = _function_address(dll, "hs_root")
        self._advance = dll["hs_advance"]
        p, long_p = ctypes.c_void_p, ctypes.POINTER(ctypes.c_long)
        self._advance.argtypes = [p, p, p, p, ctypes.c_double, p, ctypes.c_long, long_p, ctypes.c_int, p, p,
                                  ctypes.c_long, long_p, ctypes.POINTER(ctypes.c_double), long_p, ctypes.c_long,
                                  ctypes.POINTER(ctypes.c_int)]
        self._advance.restype = ctypes.c_int
        self._set_stop_time = sundials_cvode["CVodeSetStopTime"]
        self._set_stop_time.argtypes, self._set_stop_time.restype = [p, ctypes.c_double], ctypes.c_int

    def advance(self, solver: NativeSolver, t_stop: float, grid: np.ndarray, next_output: int,
                interpolate: bool, max_steps: int, take_rows: Callable[[np.ndarray, np.ndarray], None]):
        """CVODE in one-step mode up to ``t_stop`` or the first root, the loop over internal steps in C.

        Rows (time, master inputs, traced outputs) are recorded after each internal step but the
        last (kind 0) and, with ``interpolate``, at the output times ``grid[next_output:]`` passed
        on the way, from CVODE's interpolating polynomial (kind 1); ``take_rows(rows, kinds)`` gets
        them in blocks, in time order (views valid during the call only; it may raise to stop).
        Returns (root found, time reached, index of the next output time); the FMUs then hold
        the solution at the time reached. When an FMU fails, its error stays recorded for
        :meth:`take_error` (with the time of the failing evaluation) and RuntimeError is raised.
        """
        if not solver.discrete:
            solver.get_x(solver.px, solver.nx)
        if self._set_stop_time(solver.cvode_mem, t_stop) < 0:
            raise RuntimeError(f"CVodeSetStopTime({t_stop}) failed")
        grid = np.ascontiguousarray(grid, dtype=float)
        next_index, n_rows, steps = ctypes.c_long(next_output), ctypes.c_long(0), ctypes.c_long(0)
        reached, flag = ctypes.c_double(np.nan), ctypes.c_int(0)
        while True:
            n_rows.value = 0
            status = self._advance(self.user_data, solver.cvode_mem, solver.x, solver.dky, t_stop,
                                   grid.ctypes.data, len(grid), ctypes.byref(next_index), int(interpolate),
                                   self.rows.ctypes.data, self.kinds.ctypes.data, self.ROWS_PER_BLOCK,
                                   ctypes.byref(n_rows), ctypes.byref(reached), ctypes.byref(steps), max_steps,
                                   ctypes.byref(flag))
            for fmu in self.instances:
                fmu.time = reached.value
            if n_rows.value:
                take_rows(self.rows[:n_rows.value], self.kinds[:n_rows.value])
            if status == ADVANCE_FULL:
                continue
            if status in (ADVANCE_REACHED, ADVANCE_ROOT):
                if not solver.discrete:
                    solver.set_x(solver.px, solver.nx)
                return status == ADVANCE_ROOT, float(reached.value), int(next_index.value)
            if status == ADVANCE_FMU_FAILED:  # the error stays recorded for the master (take_error)
                raise RuntimeError("an FMU failed inside the compiled one-step loop")
            if status == ADVANCE_MAX_STEPS:
                raise too_many_steps(max_steps, t_stop, reached.value)
            if status == ADVANCE_DKY_FAILED:
                raise RuntimeError(f"CVodeGetDky failed between t = {reached.value:.9g} s and the step before")
            raise cvode_failure(solver.error_info, flag.value)

    @property
    def rhs_count(self) -> int:
        return int(self.state.rhs_count)

    def take_error(self):
        """The FMIError of a failed evaluation (the FMU's messages, the true time), or None; clears it."""
        if not self.state.status:
            return None
        fmu = self.instances[self.state.failed_unit]
        time = float(self.state.failed_time)
        fmu.time = time
        error = fmu._error(FUNCTIONS[self.state.failed_function], int(self.state.status))
        self.state.status = 0
        return error, time


class NativeSolver:
    """CVODE (BDF, Newton, dense linear solver, root finding) on the compiled kernel.

    Offers what the master uses of fmpy's ``CVodeSolver``: ``step``, ``reset``, ``x``, ``px``,
    ``nx``, ``discrete``, ``cvode_mem``, ``sunctx``, ``error_info``, ``get_x``/``set_x``.
    """

    def __init__(self, kernel: Kernel, nx, nz, get_x, set_x, get_nominals, startTime,
                 maxStep=float("inf"), relativeTolerance=1e-5, maxNumSteps=500):
        from fmpy.sundials import (
            CV_BDF,
            NV_DATA_S,
            SUN_COMM_NULL,
            CVodeCreate,
            CVodeFree,
            CVodeSetLinearSolver,
            CVodeSetMaxNumSteps,
            CVodeSetMaxStep,
            CVodeSetNoInactiveRootWarn,
            CVodeSVtolerances,
            N_VNew_Serial,
            SUNContext,
            SUNContext_Create,
            SUNContext_PushErrHandler,
            SUNDenseMatrix,
            SUNErrHandlerFn,
            SUNLinSol_Dense,
        )
        from fmpy.sundials.cvode import sundials_cvode

        self.kernel = kernel
        self.get_x, self.set_x, self.get_nominals = get_x, set_x, get_nominals
        self.error_info = None
        self.reltol = relativeTolerance
        self.discrete = nx == 0
        self.nx = 1 if self.discrete else nx
        self.nz = nz
        self.sunctx = SUNContext()
        self._check(SUNContext_Create(SUN_COMM_NULL, ctypes.byref(self.sunctx)), "SUNContext_Create")
        self.x = N_VNew_Serial(self.nx, self.sunctx)
        self.abstol = N_VNew_Serial(self.nx, self.sunctx)
        self.dky = N_VNew_Serial(self.nx, self.sunctx)  # interpolated states (Kernel.advance)
        self.px = NV_DATA_S(self.x)
        self.pabstol = NV_DATA_S(self.abstol)
        self.npabstol = np.ctypeslib.as_array(self.pabstol, (self.nx,))
        if self.discrete:
            np.ctypeslib.as_array(self.px, (self.nx,))[:] = 1.0
            self.npabstol[:] = 1.0
        else:
            self.get_x(self.px, self.nx)
            self.get_nominals(self.pabstol, self.nx)
        self.npabstol *= self.reltol
        self.cvode_mem = CVodeCreate(CV_BDF, self.sunctx)
        self._free = CVodeFree
        init = sundials_cvode["CVodeInit"]  # own function objects: fmpy's take Python callbacks
        init.argtypes = [ctypes.c_void_p, ctypes.c_void_p, ctypes.c_double, type(self.x)]
        init.restype = ctypes.c_int
        self._check(init(self.cvode_mem, kernel.rhs, startTime, self.x), "CVodeInit")
        set_user_data = sundials_cvode["CVodeSetUserData"]
        set_user_data.argtypes, set_user_data.restype = [ctypes.c_void_p, ctypes.c_void_p], ctypes.c_int
        self._check(set_user_data(self.cvode_mem, kernel.user_data), "CVodeSetUserData")
        self._check(CVodeSVtolerances(self.cvode_mem, relativeTolerance, self.abstol), "CVodeSVtolerances")
        root_init = sundials_cvode["CVodeRootInit"]
        root_init.argtypes = [ctypes.c_void_p, ctypes.c_int, ctypes.c_void_p]
        root_init.restype = ctypes.c_int
        self._check(root_init(self.cvode_mem, self.nz, kernel.root), "CVodeRootInit")
        self.A = SUNDenseMatrix(self.nx, self.nx, self.sunctx)
        self.LS = SUNLinSol_Dense(self.x, self.A, self.sunctx)
        self._check(CVodeSetLinearSolver(self.cvode_mem, self.LS, self.A), "CVodeSetLinearSolver")
        self._check(CVodeSetMaxStep(self.cvode_mem, maxStep), "CVodeSetMaxStep")
        self._check(CVodeSetMaxNumSteps(self.cvode_mem, maxNumSteps), "CVodeSetMaxNumSteps")
        self._check(CVodeSetNoInactiveRootWarn(self.cvode_mem), "CVodeSetNoInactiveRootWarn")
        self.ehfun_ = SUNErrHandlerFn(self.ehfun)
        self._check(SUNContext_PushErrHandler(self.sunctx, self.ehfun_, None), "SUNContext_PushErrHandler")

    @staticmethod
    def _check(flag: int, what: str) -> None:
        if flag != 0:
            raise RuntimeError(f"{what} failed (flag {flag})")

    def ehfun(self, line, func, file, msg, err_code, err_user_data, sunctx) -> None:
        self.error_info = (err_code, func.decode("utf-8"), file.decode("utf-8"), msg.decode("utf-8"))

    def step(self, t, tNext):
        from fmpy.sundials import CV_NORMAL, CVode

        if not self.discrete:
            self.get_x(self.px, self.nx)
        reached = ctypes.c_double(0.0)
        flag = CVode(self.cvode_mem, tNext, self.x, ctypes.byref(reached), CV_NORMAL)
        if flag < 0:  # (the FMUs are not touched: an FMU in its error state keeps its messages)
            raise cvode_failure(self.error_info, flag)
        if not self.discrete:
            self.set_x(self.px, self.nx)
        return flag > 0, None, reached.value

    def reset(self, time):
        from fmpy.sundials import CVodeReInit

        if not self.discrete:
            self.get_x(self.px, self.nx)
            self.get_nominals(self.pabstol, self.nx)
            self.npabstol *= self.reltol
        self._check(CVodeReInit(self.cvode_mem, time, self.x), "CVodeReInit")

    def __del__(self):
        if getattr(self, "cvode_mem", None):
            self._free(ctypes.byref(ctypes.c_void_p(self.cvode_mem)))
            self.cvode_mem = None
