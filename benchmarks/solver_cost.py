"""What sets the solver's work per motor step (prints figures; not a test).

    .venv/bin/python benchmarks/solver_cost.py

On the paper's 5-minute case (scenarios/jan21-central.yaml, 16 motor steps), with the compiled
kernel, per motor step:

1. CVODE's own counters (read through SUNDIALS' C API before every restart and at the end):
   internal steps, RHS evaluations (the master's count, difference-quotient Jacobians
   included), error-test failures, Newton convergence failures, Jacobian evaluations;
2. where the internal steps fall after the step that started their interval (rows of kind
   "solver step" only, not output rows);
3. the same counters for variants that each remove one suspect: a lower maximum BDF order, a
   smooth chopper (``V_supply tanh(K_current (i_ref - i) / V_supply)``: same gain and limit,
   no corner; generated into a temporary models folder), wider friction regularisation, no
   Coulomb friction, a looser tolerance. Each line also prints the peak torque, to show how
   far the variant is from the shipped physics.
"""

from __future__ import annotations

import collections
import ctypes
import os
import shutil
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
SCENARIO = ROOT / "scenarios" / "jan21-central.yaml"
COUNTERS = ("NumSteps", "NumErrTestFails", "NumNonlinSolvConvFails", "NumJacEvals", "NumLinRhsEvals")
EDGES_MS = (0, 1, 2, 5, 10, 20, 50, 100, 1000, np.inf)


class Probe:
    """CVODE's counters summed over the run's restarts, optionally a maximum order; the solver
    step rows' times."""

    def __init__(self, max_order: int | None = None):
        self.max_order, self.totals, self.step_times = max_order, collections.Counter(), []

    def __enter__(self):
        from fmpy.sundials.libraries import sundials_cvode

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
        self._classes = (solver, run)
        return self

    def __exit__(self, *exc):
        solver, run = self._classes
        solver.__init__, solver.reset, solver.close, run._take_rows = self._saved


def measure(overrides=(), max_order=None):
    """(run, CVODE counters, solver step times) of the paper's case with ``overrides``."""
    import gc

    from heliostep.run import run_scenario

    with Probe(max_order) as probe:
        run = run_scenario(SCENARIO, tuple(overrides))
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


def main() -> None:
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
