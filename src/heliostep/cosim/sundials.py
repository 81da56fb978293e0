"""Every SUNDIALS binding of heliostep: the CVODE, N_Vector and dense-solver functions it calls.

The shared libraries are the ones fmpy ships (:mod:`fmpy.sundials.libraries`, SUNDIALS 7). The
functions that take a callback are bound here with plain ``void *`` arguments, so CVODE can be
given the address of any C function: the compiled kernel's ``hs_rhs``/``hs_root`` or a ctypes
callback (:data:`RHS_CALLBACK`, :data:`ROOT_CALLBACK`). Each function object is this module's own
(``library["name"]``), never fmpy's, so the prototypes set here and fmpy's never meet.
No other module of heliostep binds a SUNDIALS function.
"""

from __future__ import annotations

import ctypes
from ctypes import POINTER, c_char_p, c_double, c_int, c_int64, c_long, c_void_p

from fmpy.sundials.libraries import (
    sundials_core,
    sundials_cvode,
    sundials_nvecserial,
    sundials_sunlinsoldense,
    sundials_sunmatrixdense,
)

#: cvode.h: the BDF method, the tasks of ``CVode`` and what it returns on success.
CV_BDF = 2
CV_NORMAL, CV_ONE_STEP = 1, 2
CV_SUCCESS, CV_TSTOP_RETURN, CV_ROOT_RETURN = 0, 1, 2

#: ``int f(double t, N_Vector y, N_Vector ydot, void *user_data)``: CVODE's right-hand side.
RHS_CALLBACK = ctypes.CFUNCTYPE(c_int, c_double, c_void_p, c_void_p, c_void_p)
#: ``int g(double t, N_Vector y, double *gout, void *user_data)``: CVODE's root function.
ROOT_CALLBACK = ctypes.CFUNCTYPE(c_int, c_double, c_void_p, c_void_p, c_void_p)
#: ``void handler(int line, const char *function, const char *file, const char *message,
#: SUNErrCode code, void *user_data, SUNContext context)``: SUNDIALS' error handler.
ERROR_HANDLER = ctypes.CFUNCTYPE(None, c_int, c_char_p, c_char_p, c_char_p, c_int, c_void_p, c_void_p)


def _bind(library: ctypes.CDLL, name: str, restype, *argtypes):
    function = library[name]  # a new function object: fmpy's own stay as fmpy set them
    function.argtypes, function.restype = list(argtypes), restype
    return function


# context and vectors
SUN_COMM_NULL = 0  # SUNComm is an int without MPI
SUNContext_Create = _bind(sundials_core, "SUNContext_Create", c_int, c_int, POINTER(c_void_p))
SUNContext_PushErrHandler = _bind(sundials_core, "SUNContext_PushErrHandler", c_int, c_void_p, ERROR_HANDLER, c_void_p)
SUNContext_ClearErrHandlers = _bind(sundials_core, "SUNContext_ClearErrHandlers", c_int, c_void_p)
N_VNew_Serial = _bind(sundials_nvecserial, "N_VNew_Serial", c_void_p, c_int64, c_void_p)
N_VGetArrayPointer = _bind(sundials_nvecserial, "N_VGetArrayPointer", c_void_p, c_void_p)
# dense Jacobian and linear solver
SUNDenseMatrix = _bind(sundials_sunmatrixdense, "SUNDenseMatrix", c_void_p, c_int64, c_int64, c_void_p)
SUNLinSol_Dense = _bind(sundials_sunlinsoldense, "SUNLinSol_Dense", c_void_p, c_void_p, c_void_p, c_void_p)
# CVODE
CVodeCreate = _bind(sundials_cvode, "CVodeCreate", c_void_p, c_int, c_void_p)
CVodeInit = _bind(sundials_cvode, "CVodeInit", c_int, c_void_p, c_void_p, c_double, c_void_p)
CVodeSetUserData = _bind(sundials_cvode, "CVodeSetUserData", c_int, c_void_p, c_void_p)
CVodeSVtolerances = _bind(sundials_cvode, "CVodeSVtolerances", c_int, c_void_p, c_double, c_void_p)
CVodeRootInit = _bind(sundials_cvode, "CVodeRootInit", c_int, c_void_p, c_int, c_void_p)
CVodeSetLinearSolver = _bind(sundials_cvode, "CVodeSetLinearSolver", c_int, c_void_p, c_void_p, c_void_p)
CVodeSetMaxStep = _bind(sundials_cvode, "CVodeSetMaxStep", c_int, c_void_p, c_double)
CVodeSetMaxNumSteps = _bind(sundials_cvode, "CVodeSetMaxNumSteps", c_int, c_void_p, c_long)
CVodeSetNoInactiveRootWarn = _bind(sundials_cvode, "CVodeSetNoInactiveRootWarn", c_int, c_void_p)
CVodeSetStopTime = _bind(sundials_cvode, "CVodeSetStopTime", c_int, c_void_p, c_double)
CVode = _bind(sundials_cvode, "CVode", c_int, c_void_p, c_double, c_void_p, POINTER(c_double), c_int)
CVodeReInit = _bind(sundials_cvode, "CVodeReInit", c_int, c_void_p, c_double, c_void_p)
CVodeFree = _bind(sundials_cvode, "CVodeFree", None, POINTER(c_void_p))


def function_address(library: ctypes.CDLL, name: str) -> int:
    """The address of the C function ``name`` of ``library`` (for C code that calls it)."""
    return ctypes.cast(library[name], c_void_p).value or 0


def cvode_address(name: str) -> int:
    """The address of a CVODE function (``CVode``, ``CVodeGetDky``) for the compiled kernel."""
    return function_address(sundials_cvode, name)


def vector_data_address() -> int:
    """The address of ``N_VGetArrayPointer`` (the compiled kernel reads CVODE's vectors with it)."""
    return function_address(sundials_nvecserial, "N_VGetArrayPointer")
