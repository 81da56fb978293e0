"""The cost of one algebraic loop: a system with one vs the same system without it (prints figures; not a test).

    .venv/bin/python benchmarks/bench_loops.py [--repeat 3] [--stop 2.0]

Issue #26 (and #24): one algebraic loop anywhere in a system used to switch the whole system to the
Python callbacks (35x slower); the loop is now solved inside the compiled kernel (Newton in C,
``src/heliostep/cosim/c/kernel.c``, ``solve_loop``) and the rest of the system stays compiled. Goal:
the system with one loop within 1.5x of the same system without it.

The system: the shipped drive (StepperMotor and PanelMechanics, the test suite's connections and step
sequence, rtol 1e-6) and two extra mini FMUs from ``tests/data/mini``, a Lag (T dy/dt = e, e = u - y)
and a Gain (y = k u + b). With the loop: ``lag.e -> g.u`` and ``g.y -> lag.u`` (u = k (u - y) + b, a
loop whose solution moves with the Lag's state: every evaluation takes a Newton iteration, three loop
evaluations). Without it: only ``lag.e -> g.u`` (the same FMUs, states and connections less one).
Printed, best of ``--repeat`` in one run: the simulation's wall time and RHS evaluations on each path
(without the loop, with it compiled, with it on the Python callbacks as before), then one line for
scripts: ``loop: <s> s, no loop <s> s, ratio <r>, python loop <s> s, ratio <r>``.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests" / "support"))

import heliostep.cosim.integrator as integrator  # noqa: E402
from heliostep.cosim import Connection, CoSimulation, PiecewiseConstant, SolverOptions, read_fmu  # noqa: E402
from heliostep.cosim.integrator import compiled_kernel  # noqa: E402
from heliostep.drive.sequencer import Sequencer  # noqa: E402
from heliostep.fmu.build import build_fmu  # noqa: E402
from third_party_fmu import build_mini_fmu  # noqa: E402  (the tests' mini FMUs, compiled here)

DRIVE = [
    Connection("motor.tau", "mechanics.tau"),
    Connection("mechanics.theta", "motor.theta"),
    Connection("mechanics.omega", "motor.omega"),
]
LOOP = [Connection("lag.e", "g.u"), Connection("g.y", "lag.u")]


def system(fmus: dict, with_loop: bool, stop: float) -> CoSimulation:
    """The drive stepping every 0.1 s and the Lag and Gain, looped or not."""
    steps = np.arange(0.05, stop, 0.1)
    i_a, i_b = Sequencer().reference_currents(np.arange(len(steps) + 1) % 8)
    inputs = [
        PiecewiseConstant("i_a_ref", "motor.i_a_ref", steps, i_a),
        PiecewiseConstant("i_b_ref", "motor.i_b_ref", steps, i_b),
    ]
    connections = DRIVE + (LOOP if with_loop else LOOP[:1])
    parameters = {"lag": {"T": 0.5}, "g": {"k": 0.5, "b": 1.0}}
    return CoSimulation(fmus, connections, inputs, parameters=parameters)


def measure(fmus: dict, with_loop: bool, compiled: bool, stop: float, repeat: int) -> tuple[float, dict]:
    """Best simulation wall time [s] of ``repeat`` runs, and the last run's statistics."""
    integrator.compiled_kernel = compiled_kernel if compiled else (lambda *args: None)
    grid = np.round(np.arange(0.0, stop + 1e-9, 1e-3), 12)
    best, statistics = np.inf, {}
    for _ in range(repeat):
        co = system(fmus, with_loop, stop)
        began = time.perf_counter()
        result = co.simulate(0.0, stop, grid, SolverOptions(rtol=1e-6), monitor=lambda rows: None)
        best = min(best, time.perf_counter() - began)
        statistics = result.statistics
    return best, statistics


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--stop", type=float, default=2.0, help="simulated time [s]")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as work:
        fmus = {
            "motor": read_fmu(build_fmu("StepperMotor")),
            "mechanics": read_fmu(build_fmu("PanelMechanics")),
            "lag": read_fmu(build_mini_fmu("Lag", Path(work))),
            "g": read_fmu(build_mini_fmu("Gain", Path(work))),
        }
        figures = {}
        for label, with_loop, compiled in (
            ("no loop, compiled", False, True),
            ("one loop, compiled (Newton in C)", True, True),
            ("one loop, Python callbacks", True, False),
        ):
            seconds, stats = measure(fmus, with_loop, compiled, args.stop, args.repeat)
            figures[label] = seconds
            loops = (
                f", loop solves {stats['loop_solves']}, Newton iterations {stats['loop_iterations']}"
                if with_loop
                else ""
            )
            print(f"{label:34s} {seconds:7.3f} s  rhs {stats['rhs']:6d}  compiled_rhs {stats['compiled_rhs']}{loops}")
    no_loop, loop, python = figures.values()
    print(
        f"loop: {loop:.3f} s, no loop {no_loop:.3f} s, ratio {loop / no_loop:.2f}, "
        f"python loop {python:.3f} s, ratio {python / no_loop:.2f}"
    )


if __name__ == "__main__":
    main()
