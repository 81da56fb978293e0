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

The C source is compiled with the system C compiler (``$CC`` or ``cc``) at first use into a
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
from pathlib import Path

import numpy as np

from heliostep.errors import HeliostepError
from heliostep.paths import fmus_dir
from heliostep.toolchain import compiler_version, exclusive_lock

SOURCE = r"""
#include <stddef.h>
typedef void *fmi2Component;
typedef int (*set_time_t)(fmi2Component, double);
typedef int (*set_x_t)(fmi2Component, const double *, size_t);
typedef int (*get_x_t)(fmi2Component, double *, size_t);
typedef int (*get_real_t)(fmi2Component, const unsigned int *, size_t, double *);
typedef int (*set_real_t)(fmi2Component, const unsigned int *, size_t, const double *);
typedef double *(*data_t)(void *);

typedef struct {
    fmi2Component component;
    set_time_t set_time;
    set_x_t set_states;
    get_x_t get_derivatives;
    get_x_t get_event_indicators;
    get_real_t get_real;
    set_real_t set_real;
    long nx, x_offset, nz, z_offset;
} hs_unit;

typedef struct {
    long source, target, n;
    const unsigned int *source_vrs, *target_vrs;
    double *buffer;
} hs_link;

typedef struct {
    long n_units;
    hs_unit *units;
    long n_links;
    hs_link *links;
    data_t data;              /* N_VGetArrayPointer */
    long discrete, nx;
    long rhs_count;
    long status, failed_unit, failed_function;
    double failed_time;
} hs_kernel;

enum { F_SET_TIME, F_SET_STATES, F_GET_REAL, F_SET_REAL, F_GET_DERIVATIVES, F_GET_EVENT_INDICATORS };

static int fail(hs_kernel *k, int status, long unit, long function, double t) {
    k->status = status;
    k->failed_unit = unit;
    k->failed_function = function;
    k->failed_time = t;
    return -1;
}

#define CHECK(call, unit, function) \
    do { int s_ = (call); if (s_ > 1) return fail(k, s_, (unit), (function), t); } while (0)

/* set time (and states), propagate the continuous connections */
static int evaluate(hs_kernel *k, double t, const double *x) {
    long i;
    for (i = 0; i < k->n_units; i++) {
        hs_unit *u = &k->units[i];
        CHECK(u->set_time(u->component, t), i, F_SET_TIME);
    }
    if (k->discrete) return 0;
    for (i = 0; i < k->n_units; i++) {
        hs_unit *u = &k->units[i];
        if (u->nx) CHECK(u->set_states(u->component, x + u->x_offset, (size_t)u->nx), i, F_SET_STATES);
    }
    return 0;
}

static int propagate(hs_kernel *k, double t) {
    long j;
    for (j = 0; j < k->n_links; j++) {
        hs_link *l = &k->links[j];
        hs_unit *s = &k->units[l->source], *d = &k->units[l->target];
        CHECK(s->get_real(s->component, l->source_vrs, (size_t)l->n, l->buffer), l->source, F_GET_REAL);
        CHECK(d->set_real(d->component, l->target_vrs, (size_t)l->n, l->buffer), l->target, F_SET_REAL);
    }
    return 0;
}

int hs_rhs(double t, void *y, void *ydot, void *user_data) {
    hs_kernel *k = (hs_kernel *)user_data;
    double *x = k->data(y), *dx = k->data(ydot);
    long i;
    if (k->status) return -1;
    if (evaluate(k, t, x)) return -1;
    if (k->discrete) {
        for (i = 0; i < k->nx; i++) dx[i] = 0.0;
        return 0;
    }
    k->rhs_count++;
    if (propagate(k, t)) return -1;
    for (i = 0; i < k->n_units; i++) {
        hs_unit *u = &k->units[i];
        if (u->nx) CHECK(u->get_derivatives(u->component, dx + u->x_offset, (size_t)u->nx), i, F_GET_DERIVATIVES);
    }
    return 0;
}

/* the FMUs at (t, x) with their connections propagated: for recording a solver step */
int hs_prepare(hs_kernel *k, double t, const double *x) {
    if (k->status) return -1;
    if (evaluate(k, t, x)) return -1;
    return propagate(k, t);
}

int hs_root(double t, void *y, double *gout, void *user_data) {
    hs_kernel *k = (hs_kernel *)user_data;
    long i;
    if (k->status) return -1;
    if (evaluate(k, t, k->data(y))) return -1;
    if (propagate(k, t)) return -1;
    for (i = 0; i < k->n_units; i++) {
        hs_unit *u = &k->units[i];
        if (u->nz)
            CHECK(u->get_event_indicators(u->component, gout + u->z_offset, (size_t)u->nz), i,
                  F_GET_EVENT_INDICATORS);
    }
    return 0;
}
"""

#: The FMI function of each ``failed_function`` code of the C kernel.
FUNCTIONS = ["fmi2SetTime", "fmi2SetContinuousStates", "fmi2GetReal", "fmi2SetReal", "fmi2GetDerivatives",
             "fmi2GetEventIndicators"]


class _Unit(ctypes.Structure):
    _fields_ = [("component", ctypes.c_void_p)] + [
        (name, ctypes.c_void_p) for name in ("set_time", "set_states", "get_derivatives", "get_event_indicators",
                                             "get_real", "set_real")] + [
        (name, ctypes.c_long) for name in ("nx", "x_offset", "nz", "z_offset")]


class _Link(ctypes.Structure):
    _fields_ = [("source", ctypes.c_long), ("target", ctypes.c_long), ("n", ctypes.c_long),
                ("source_vrs", ctypes.c_void_p), ("target_vrs", ctypes.c_void_p), ("buffer", ctypes.c_void_p)]


class _Kernel(ctypes.Structure):
    _fields_ = [("n_units", ctypes.c_long), ("units", ctypes.POINTER(_Unit)), ("n_links", ctypes.c_long),
                ("links", ctypes.POINTER(_Link)), ("data", ctypes.c_void_p), ("discrete", ctypes.c_long),
                ("nx", ctypes.c_long), ("rhs_count", ctypes.c_long), ("status", ctypes.c_long),
                ("failed_unit", ctypes.c_long), ("failed_function", ctypes.c_long),
                ("failed_time", ctypes.c_double)]


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
    digest = hashlib.sha256(SOURCE.encode() + b"\0" + version.encode()).hexdigest()[:24]
    folder = kernels_dir()
    path = folder / f"heliostep_kernel_{digest}.so"
    if path.exists():
        return path
    with exclusive_lock(folder / ".lock"):
        if path.exists():
            return path
        with tempfile.TemporaryDirectory(dir=folder) as work:
            source = Path(work) / "kernel.c"
            source.write_text(SOURCE)
            target = Path(work) / path.name
            result = subprocess.run([cc, "-O2", "-shared", "-fPIC", "-o", str(target), str(source)],
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

    ``units`` is a list of (ModelExchangeInstance, state offset, indicator offset) in the master's
    order; ``links`` a list of (source index, target index, source value references, target value
    references) of the continuous Real connections in the master's propagation order.
    """

    def __init__(self, units, links, n_states: int):
        from fmpy.sundials.libraries import sundials_nvecserial

        self.instances = [fmu for fmu, _, _ in units]
        self._units = (_Unit * max(1, len(units)))()
        for k, (fmu, x_offset, z_offset) in enumerate(units):
            dll = fmu._model.dll
            u = self._units[k]
            u.component = fmu._component
            u.set_time = _function_address(dll, "fmi2SetTime")
            u.set_states = _function_address(dll, "fmi2SetContinuousStates")
            u.get_derivatives = _function_address(dll, "fmi2GetDerivatives")
            u.get_event_indicators = _function_address(dll, "fmi2GetEventIndicators")
            u.get_real = _function_address(dll, "fmi2GetReal")
            u.set_real = _function_address(dll, "fmi2SetReal")
            u.nx, u.x_offset, u.nz, u.z_offset = fmu.n_states, x_offset, fmu.n_event_indicators, z_offset
        self._keep = []
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
        self.user_data = ctypes.cast(ctypes.pointer(self.state), ctypes.c_void_p)
        dll = library()
        self.rhs = _function_address(dll, "hs_rhs")
        self.root = _function_address(dll, "hs_root")
        self._prepare = dll["hs_prepare"]
        self._prepare.argtypes = [ctypes.c_void_p, ctypes.c_double, ctypes.POINTER(ctypes.c_double)]
        self._prepare.restype = ctypes.c_int

    def prepare(self, t: float, x) -> None:
        """Set time ``t`` and the states at ``x`` (a pointer to doubles) into every FMU and
        propagate the continuous connections, in C; an FMI error is raised as FMIError."""
        if self._prepare(self.user_data, t, x):
            failed = self.take_error()
            if failed is not None:
                raise failed[0]
            raise RuntimeError("the compiled kernel refused to evaluate")
        for fmu in self.instances:
            fmu.time = t

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
            raise RuntimeError("CVode error (code %s) in module %s, function %s: %s" % self.error_info)
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
