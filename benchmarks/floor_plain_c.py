"""The floor: the shipped drive's equations as a plain C right-hand side on the same CVODE, beside heliostep.

    .venv/bin/python benchmarks/floor_plain_c.py [scenario] [--repeat 3]

Every speed figure as a ratio to the floor, measured side by side in one run. The C right-hand
side below is written by hand from ``models/StepperMotor.mo`` and ``models/PanelMechanics.mo`` (the paper's
eqs. 7-9 with the averaged chopper and the Simscape block's iron loss and detent terms; eqs. 10-15, exact
kinematics, rotor damping B_m, tanh-smoothed Coulomb friction), not generated: four states (i_a, i_b,
theta_p, omega_p), the same parameters, the same initial state (the
drive's holding equilibrium, from :func:`heliostep.drive.inputs.prepare_inputs`). The parameters are
heliostep's own (:func:`heliostep_parameters`: the FMUs' start values, then what the runner sets), so the
floor solves heliostep's problem (the motor's detent torque included). It runs on the CVODE that fmpy ships, as
heliostep's master does: BDF, Newton with a dense difference-quotient Jacobian, rtol = the scenario's,
atol = rtol x the FMUs' nominals (all 1: the same vector as heliostep's), no step limit, restarted at every
step instant (``CVodeReInit``, the master's time event), with ``CVodeSetStopTime`` at the next one; no rows
recorded. (heliostep steps CVODE in one-step mode and interpolates its output rows: the same internal steps.)

Prints the final panel angle's difference between heliostep's run and the floor's (the same equations:
they agree to the tolerance), then per repeat the simulation time of heliostep (``statistics.wall_time``
of ``run_scenario`` without a trace: the figures still come from every solver step) and of the floor,
their ratio and the RHS evaluations of each. Default scenario: ``jan21-day`` (sunrise to sunset).
"""

from __future__ import annotations

import argparse
import ctypes
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from heliostep.cosim import sundials
from heliostep.drive.inputs import prepare_inputs
from heliostep.run import RunOptions, run_scenario
from heliostep.run.bindings import parameters, present_roles
from heliostep.run.fmus import read_fmus, resolve_fmus
from heliostep.scenario import load_scenario

C_SOURCE = r"""
#include <math.h>
typedef double *(*array_of)(void *);
typedef struct {
    double L, R, k_e, N_c, V, K, G_m, T_d;     /* StepperMotor (Table 3, the chopper, iron loss, detent) */
    double J_p, J_m, b, B_m, T_c, M_c, w_s, r, s; /* PanelMechanics (Table 2, catalogue, damping, friction) */
    double theta_p0, theta0;                    /* the rotor angle at theta_p0 */
    double i_a_ref, i_b_ref, m_ext;             /* inputs, held between steps */
    array_of data;                              /* N_VGetArrayPointer */
    long rhs_calls;
} drive;

static double clamp(double v, double limit) { return v > limit ? limit : (v < -limit ? -limit : v); }

int drive_rhs(double t, void *y, void *ydot, void *user) {
    drive *p = (drive *)user;
    const double *x = p->data(y);
    double *dx = p->data(ydot);
    double i_a = x[0], i_b = x[1], theta_p = x[2], omega_p = x[3];
    double c = cos(theta_p), tan_p = tan(theta_p);
    double g = p->s / (p->r * c * c);                                       /* eq. 15 */
    double theta = p->theta0 + p->s / p->r * (tan_p - tan(p->theta_p0));  /* eqs. 12-14 */
    double omega = g * omega_p;
    double sn = sin(p->N_c * theta), cs = cos(p->N_c * theta);
    double v_a = clamp(p->K * (p->i_a_ref - i_a), p->V), v_b = clamp(p->K * (p->i_b_ref - i_b), p->V);
    double tau = -p->k_e * (i_a + p->G_m * p->k_e * omega * sn) * sn         /* eq. 9, Simscape's losses */
                 - p->k_e * (i_b + p->G_m * p->k_e * omega * cs) * cs - p->T_d * sin(4.0 * p->N_c * theta);
    double friction = (p->T_c + p->M_c * p->r * c * c / p->s) * tanh(omega / p->w_s);
    (void)t;
    dx[0] = (v_a - p->R * i_a + p->k_e * omega * sn) / p->L;                /* eq. 7 */
    dx[1] = (v_b - p->R * i_b + p->k_e * omega * cs) / p->L;                /* eq. 8 */
    dx[2] = omega_p;
    dx[3] = (g * (tau - friction - p->B_m * omega) - p->b * omega_p - p->m_ext
             - p->J_m * g * 2.0 * g * tan_p * omega_p * omega_p)
            / (p->J_p + p->J_m * g * g);                                    /* eq. 10, exact form */
    p->rhs_calls++;
    return 0;
}
"""

FIELDS = "L R k_e N_c V K G_m T_d J_p J_m b B_m T_c M_c w_s r s theta_p0 theta0 i_a_ref i_b_ref m_ext".split()


class Drive(ctypes.Structure):
    _fields_ = [(name, ctypes.c_double) for name in FIELDS] + [("data", ctypes.c_void_p), ("rhs_calls", ctypes.c_long)]


def compile_floor(folder: Path) -> ctypes.CDLL:
    source, library = folder / "drive_rhs.c", folder / "drive_rhs.so"
    source.write_text(C_SOURCE)
    subprocess.run(["gcc", "-O2", "-shared", "-fPIC", "-o", str(library), str(source), "-lm"], check=True)
    return ctypes.CDLL(str(library))


def heliostep_parameters(scenario, inputs) -> dict[str, dict[str, float]]:
    """Every parameter of the motor and the mechanics as heliostep's run sets them: the FMUs' start values
    (``modelDescription.xml``), then what the scenario implies and the user's (:func:`heliostep.run.bindings.
    parameters`, the runner's own call). The floor's right-hand side then solves heliostep's problem, not one
    with defaults of its own (before 2026-12-02 it left out the motor's detent torque T_d = 0.094 N.m)."""
    infos = read_fmus(scenario, resolve_fmus(scenario))
    values = parameters(scenario, inputs, present_roles(scenario, infos), infos)
    every = {}
    for name in ("motor", "mechanics"):
        starts = infos[name].variables.values()
        every[name] = {v.name: float(v.start) for v in starts if v.causality == "parameter" and v.start is not None}
        every[name].update({key: float(value) for key, value in values[name].items()})
    return every


def _parameters(scenario, inputs) -> Drive:
    every = heliostep_parameters(scenario, inputs)
    motor, mechanics = every["motor"], every["mechanics"]
    return Drive(
        L=motor["L"], R=motor["R"], k_e=motor["k_e"], N_c=motor["N_c"], V=motor["V_supply"], K=motor["K_current"],
        G_m=motor["G_m"], T_d=motor["T_d"], B_m=mechanics["B_m"],
        J_p=mechanics["J_p"], J_m=mechanics["J_m"], b=mechanics["b"], T_c=mechanics["T_c"], M_c=mechanics["M_c"],
        w_s=mechanics["w_s"], r=mechanics["r"], s=mechanics["s"],
        theta_p0=mechanics["theta_p_start"], theta0=mechanics["theta_start"],
        m_ext=inputs.wind_moment, data=sundials.vector_data_address(),
    )  # fmt: skip


def floor_run(library: ctypes.CDLL, scenario, inputs) -> tuple[float, int, float]:
    """The floor's simulation time [s], its RHS calls and the final panel angle [rad]."""
    drive = _parameters(scenario, inputs)
    rtol = scenario.solver.rtol
    context = ctypes.c_void_p()
    sundials.SUNContext_Create(sundials.SUN_COMM_NULL, ctypes.byref(context))
    x, atol = (sundials.N_VNew_Serial(4, context) for _ in range(2))
    state = np.ctypeslib.as_array(ctypes.cast(sundials.N_VGetArrayPointer(x), ctypes.POINTER(ctypes.c_double)), (4,))
    tolerance = np.ctypeslib.as_array(
        ctypes.cast(sundials.N_VGetArrayPointer(atol), ctypes.POINTER(ctypes.c_double)), (4,)
    )
    held = drive.K / (drive.K + drive.R)  # the loop's holding equilibrium, as the motor FMU starts
    state[:] = [held * inputs.current_a_ref[0], held * inputs.current_b_ref[0], drive.theta_p0, 0.0]
    tolerance[:] = rtol
    drive.i_a_ref, drive.i_b_ref = inputs.current_a_ref[0], inputs.current_b_ref[0]
    rhs = ctypes.cast(library.drive_rhs, ctypes.c_void_p)
    started = time.perf_counter()
    memory = sundials.CVodeCreate(sundials.CV_BDF, context)
    sundials.CVodeInit(memory, rhs, 0.0, x)
    sundials.CVodeSetUserData(memory, ctypes.byref(drive))
    sundials.CVodeSVtolerances(memory, rtol, atol)
    matrix = sundials.SUNDenseMatrix(4, 4, context)
    sundials.CVodeSetLinearSolver(memory, sundials.SUNLinSol_Dense(x, matrix, context), matrix)
    sundials.CVodeSetMaxNumSteps(memory, 100_000)
    reached = ctypes.c_double()
    edges = list(inputs.schedule.times) + [inputs.duration]
    t = 0.0
    for k, stop in enumerate(edges):
        sundials.CVodeSetStopTime(memory, stop)
        flag = sundials.CVode(memory, stop, x, ctypes.byref(reached), sundials.CV_NORMAL)
        if flag < 0:
            raise RuntimeError(f"CVode failed with flag {flag} at t = {reached.value}")
        t = stop
        if k < len(inputs.schedule.times):  # the step: new reference currents, CVODE restarted there
            drive.i_a_ref, drive.i_b_ref = inputs.current_a_ref[k + 1], inputs.current_b_ref[k + 1]
            sundials.CVodeReInit(memory, t, x)
    elapsed = time.perf_counter() - started
    sundials.CVodeFree(ctypes.byref(ctypes.c_void_p(memory)))
    return elapsed, drive.rhs_calls, float(state[2])


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("scenario", nargs="?", default="jan21-day")
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args(argv)
    scenario = load_scenario(args.scenario)
    inputs = prepare_inputs(scenario)
    with tempfile.TemporaryDirectory() as folder:
        library = compile_floor(Path(folder))
        steps = len(inputs.schedule.times)
        print(f"{scenario.name}: {steps} steps over {inputs.duration:.0f} s, rtol {scenario.solver.rtol:g}")
        panel = run_scenario(scenario).trace["mechanics.theta_p"].iloc[-1]  # the same equations: the same end
        print(f"final panel angle, heliostep - floor: {panel - floor_run(library, scenario, inputs)[2]:.2e} rad")
        print(f"{'':>3} {'heliostep [s]':>14} {'floor [s]':>10} {'ratio':>6} {'RHS heliostep':>14} {'RHS floor':>10}")
        for repeat in range(args.repeat):  # side by side, alternating: the machine is shared
            ours = run_scenario(scenario, RunOptions(keep_trace=False)).metadata["statistics"]
            floor_time, floor_rhs, _ = floor_run(library, scenario, inputs)
            print(
                f"{repeat:3d} {ours['wall_time']:14.3f} {floor_time:10.3f} {ours['wall_time'] / floor_time:6.2f} "
                f"{ours['rhs']:14d} {floor_rhs:10d}"
            )
    return 0


if __name__ == "__main__":
    sys.exit(main())
