"""What sets the solver's work per motor step (prints figures; not a test).

    .venv/bin/python benchmarks/solver_cost.py [--integrators [--rtol 1e-6] [--atol X]]

Per motor step of the paper's case: CVODE's counters (internal steps, RHS evaluations, error-test and Newton
failures, Jacobians), where the internal steps fall after the step, and the same for variants that each remove
one suspect (BDF order, a smooth chopper, wider friction regularisation, no Coulomb friction, rtol). With
``--integrators``: one full step and 0.2 s of its ring in an independent numpy model of the drive (eqs. 7-10 of
the paper, not the FMUs) under scipy's BDF, Radau and LSODA at a scenario's tolerances.
"""

from __future__ import annotations

import argparse
import collections
import ctypes
import os
import shutil
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
SCENARIO = ROOT / "scenarios" / "jan21-central.yaml"
COUNTERS = ("NumSteps", "NumErrTestFails", "NumNonlinSolvConvFails", "NumJacEvals", "NumLinRhsEvals")
EDGES_MS = (0, 1, 2, 5, 10, 20, 50, 100, 1000, np.inf)


class Probe:
    """CVODE's counters summed over the run's restarts, optionally a maximum order; the solver
    step rows' times. Events go through the master's Python path, which restarts CVODE from
    Python (the counters are read there; the event in one kernel call restarts it in C)."""

    def __init__(self, max_order: int | None = None):
        self.max_order, self.totals, self.step_times = max_order, collections.Counter(), []

    def __enter__(self):
        from fmpy.sundials.libraries import sundials_cvode

        import heliostep.cosim.fast_events as fast_events
        import heliostep.cosim.integrator as integrator
        import heliostep.cosim.master as master

        probe, solver, run = self, integrator.CompiledIntegrator, master._Run
        self._saved = (solver.__init__, solver.reset, solver.close, run._take_rows)
        init, reset, close, take_rows = self._saved

        def grab(native):
            for name in COUNTERS:
                value = ctypes.c_long()
                getattr(sundials_cvode, "CVodeGet" + name)(ctypes.c_void_p(native.cvode_mem), ctypes.byref(value))
                probe.totals[name] += value.value

        def new_init(native, *args, **kwargs):
            init(native, *args, **kwargs)
            if probe.max_order is not None:
                sundials_cvode.CVodeSetMaxOrd(ctypes.c_void_p(native.cvode_mem), ctypes.c_int(probe.max_order))

        def new_reset(native, time):
            grab(native)
            return reset(native, time)

        def new_close(native):
            if native.cvode_mem:
                grab(native)
            close(native)

        def new_take_rows(self_run, rows, kinds):
            probe.step_times.append(rows[kinds != 1, 0].copy())
            return take_rows(self_run, rows, kinds)

        solver.__init__, solver.reset, solver.close, run._take_rows = new_init, new_reset, new_close, new_take_rows
        self._events = (fast_events, fast_events.compiled_events)
        fast_events.compiled_events = lambda *args: None
        self._classes = (solver, run)
        return self

    def __exit__(self, *exc):
        solver, run = self._classes
        solver.__init__, solver.reset, solver.close, run._take_rows = self._saved
        module, compiled_events = self._events
        module.compiled_events = compiled_events


def measure(overrides=(), max_order=None):
    """(run, CVODE counters, solver step times) of the paper's case with ``overrides``."""
    import gc

    from heliostep.run import run_scenario

    with Probe(max_order) as probe:
        run = run_scenario(SCENARIO, overrides=tuple(overrides))
        gc.collect()  # (the counters are read when the run closes its integrator)
    return run, probe.totals, np.concatenate(probe.step_times or [np.zeros(0)])


def line(label: str, run, totals) -> str:
    steps = max(1, int(run.summary["steps_commanded"]))
    rhs = run.metadata["statistics"]["rhs"]
    per = {name: totals[name] / steps for name in COUNTERS}
    return (
        f"  {label:48s} {per['NumSteps']:7.0f} steps {rhs / steps:7.0f} RHS "
        f"{per['NumErrTestFails']:5.1f} err.fails {per['NumNonlinSolvConvFails']:5.1f} conv.fails "
        f"{per['NumJacEvals']:5.1f} Jacobians ({per['NumLinRhsEvals']:4.0f} RHS)   "
        f"peak torque {run.summary['peak_torque_Nm']:.4f} N.m"
    )


def smooth_chopper_models(folder: Path) -> Path:
    """A models folder with the shipped models and ``StepperMotorSmoothChopper``."""
    for path in (ROOT / "models").glob("*.mo"):
        shutil.copy(path, folder / path.name)
    text = (ROOT / "models" / "StepperMotor.mo").read_text()
    text = text.replace("model StepperMotor\n", "model StepperMotorSmoothChopper\n")
    text = text.replace("end StepperMotor;", "end StepperMotorSmoothChopper;")
    for phase in ("a", "b"):
        clamp = f"v_{phase} = min(max(K_current * (i_{phase}_ref - i_{phase}), -V_supply), V_supply);"
        if clamp not in text:
            raise SystemExit(f"models/StepperMotor.mo: no line {clamp!r} to make smooth")
        text = text.replace(clamp, f"v_{phase} = V_supply * tanh(K_current * (i_{phase}_ref - i_{phase}) / V_supply);")
    (folder / "StepperMotorSmoothChopper.mo").write_text(text)
    return folder


# models/StepperMotor.mo and models/PanelMechanics.mo (Tables 2 and 3 of the paper, docs/physics.md)
L, R, K_E, N_C, V_SUPPLY, K_CURRENT = 1.8e-3, 0.1, 0.5, 50.0, 3.1, 100.0
J_P, J_M, B, T_C, M_C, W_S, R_PINION, S_LEVER = 3.37, 1.4e-4, 0.0, 0.08, 3.3e-3, 1e-2, 2.5e-3, 0.3
CURRENT = 5.5  # [A] the paper's case (scenarios/jan21-central.yaml)
THETA_P0 = 0.48  # [rad] the panel near 27.5 deg, as at 10:00 on 21 January


def rhs(_t, y, i_a_ref, i_b_ref):
    """der of (i_a, i_b, theta_p, omega_p), and the torque [N.m]."""
    i_a, i_b, theta_p, omega_p = y
    theta = S_LEVER / R_PINION * (np.tan(theta_p) - np.tan(THETA_P0))  # eqs 12-14
    g = S_LEVER / (R_PINION * np.cos(theta_p) ** 2)  # eq 15
    omega = g * omega_p
    v_a = np.clip(K_CURRENT * (i_a_ref - i_a), -V_SUPPLY, V_SUPPLY)
    v_b = np.clip(K_CURRENT * (i_b_ref - i_b), -V_SUPPLY, V_SUPPLY)
    di_a = (v_a - R * i_a + K_E * omega * np.sin(N_C * theta)) / L  # eq 7
    di_b = (v_b - R * i_b + K_E * omega * np.cos(N_C * theta)) / L  # eq 8
    torque = -K_E * i_a * np.sin(N_C * theta) - K_E * i_b * np.cos(N_C * theta)  # eq 9
    friction = (T_C + M_C * R_PINION * np.cos(theta_p) ** 2 / S_LEVER) * np.tanh(omega / W_S)
    domega_p = (g * (torque - friction) - B * omega_p - J_M * g * 2 * g * np.tan(theta_p) * omega_p**2) / (
        J_P + J_M * g**2
    )  # eq 10, the exact (Lagrangian) form
    return np.array([di_a, di_b, omega_p, domega_p]), torque


def ring_integrators(rtol: float, atol: float | None) -> None:
    """One step and its ring in the numpy model under scipy's integrators: steps, RHS, Jacobians, peak torque."""
    from scipy.integrate import solve_ivp

    atol = rtol if atol is None else atol
    held = K_CURRENT * CURRENT / (K_CURRENT + R)  # the loop's holding current, L di/dt = 0
    y0 = np.array([held, 0.0, THETA_P0, 0.0])
    print(f"one full step (phase A -> B, {CURRENT} A) and 0.2 s of ring and creep, rtol {rtol:g}, atol {atol:g}:")
    for method in ("BDF", "Radau", "LSODA"):
        started = time.perf_counter()
        solution = solve_ivp(
            lambda t, y: rhs(t, y, 0.0, CURRENT)[0], (0.0, 0.2), y0, method=method, rtol=rtol, atol=atol
        )
        wall = time.perf_counter() - started
        if not solution.success:
            print(f"  {method:6s} failed: {solution.message}")
            continue
        torque = np.array([rhs(t, y, 0.0, CURRENT)[1] for t, y in zip(solution.t, solution.y.T)])
        theta = S_LEVER / R_PINION * (np.tan(solution.y[2]) - np.tan(THETA_P0))
        ring = solution.t[(solution.t > 5e-3) & (solution.t < 50e-3)]
        print(
            f"  {method:6s} {len(solution.t) - 1:6d} steps ({len(ring):5d} of them 5-50 ms after the step) "
            f"{solution.nfev:7d} RHS {solution.njev:4d} Jacobians  peak torque {np.abs(torque).max():.4f} N.m  "
            f"rotor moved {theta[-1] / (np.pi / (2 * N_C)):+.4f} steps  ({wall:.1f} s)"
        )
    print("  CVODE (BDF) in heliostep: this script without --integrators")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--integrators", action="store_true", help="the numpy model under scipy's integrators")
    parser.add_argument("--rtol", type=float, default=1e-6)
    parser.add_argument("--atol", type=float, default=None, help="default: rtol x nominal 1, as a scenario")
    args = parser.parse_args()
    if args.integrators:
        ring_integrators(args.rtol, args.atol)
        return
    from heliostep.fmu.build import build_all

    build_all()
    run, totals, times = measure()
    print("jan21-central (16 motor steps, compiled kernel), per motor step:")
    print(line("as shipped", run, totals))
    steps = np.asarray(run.metadata["drive"]["step_times"])
    k = np.searchsorted(steps, times, side="right") - 1
    since_ms = np.where(k >= 0, (times - steps[np.clip(k, 0, None)]) * 1e3, np.inf)
    counts, _ = np.histogram(since_ms, EDGES_MS)
    print("\nwhere the internal steps fall after the step that started their interval:")
    for low, high, n in zip(EDGES_MS[:-1], EDGES_MS[1:], counts):
        print(f"  {low:6g} - {high:<6g} ms: {n / len(steps):6.1f} steps per motor step  ({n / len(times):5.1%})")

    print("\nvariants, each without one suspect:")
    for label, overrides, order in (
        ("BDF order at most 4", (), 4),
        ("BDF order at most 3", (), 3),
        ("friction regularised 10x wider (w_s 0.1)", ("parameters.mechanics.w_s=0.1",), None),
        ("friction regularised 100x wider (w_s 1)", ("parameters.mechanics.w_s=1",), None),
        ("no Coulomb friction (T_c = M_c = 0)", ("parameters.mechanics.T_c=0", "parameters.mechanics.M_c=0"), None),
        ("rtol 1e-5 instead of 1e-6", ("solver.rtol=1e-5",), None),
    ):
        run, totals, _ = measure(overrides, order)
        print(line(label, run, totals), flush=True)
    with tempfile.TemporaryDirectory(prefix="heliostep-smooth-") as scratch:
        previous = {key: os.environ.get(key) for key in ("HELIOSTEP_MODELS", "HELIOSTEP_FMUS")}
        os.environ["HELIOSTEP_MODELS"] = str(smooth_chopper_models(Path(scratch)))
        os.environ["HELIOSTEP_FMUS"] = str(Path(scratch) / "fmus")
        try:
            run, totals, _ = measure(("fmus.motor=StepperMotorSmoothChopper",))
            print(line("smooth chopper (tanh, same K_current, V_supply)", run, totals))
        finally:
            for key, value in previous.items():
                if value is None:
                    os.environ.pop(key, None)
                else:
                    os.environ[key] = value


if __name__ == "__main__":
    main()
