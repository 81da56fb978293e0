"""What the driver's two parameters do to the figures a motor is sized by: the chopper's bus voltage and its
current-loop gain.

    .venv/bin/python benchmarks/driver_sensitivity.py

1. ``jan21-central`` with the bus ``parameters.motor.V_supply`` at the paper's 3.1 V (the motor's rated
   voltage, Table 3), 24 V and 48 V (the usual SELV buses of chopper drivers; ``scenarios/jan21-48v.yaml``):
   peak torque, max tracking error, settling time, RHS evaluations per step.
2. ``jan21-paper-literal`` (no rotor inertia, damping or friction: the back-EMF through the current loop is
   the only damping) with the loop gain ``parameters.motor.K_current`` from 25 to 2 600 V/A: how long the
   torque rings after the first step, until it stays below 5 % of its peak (the paper's Figs. 11 and 14
   show a decay of about 3 s).

Prints a table for each; not a test (about 20 runs, a minute or two).
"""

from __future__ import annotations

import numpy as np

from heliostep.paths import scenarios_dir
from heliostep.run import run_scenario

SCENARIOS = scenarios_dir()


def bus_voltage_table() -> None:
    print("jan21-central by bus voltage (K_current = 100 V/A)")
    print(
        f"{'V_supply [V]':>12} {'peak torque [N m]':>18} {'max error [deg]':>16} {'settling [ms]':>14} {'RHS/step':>9}"
    )
    for bus in (3.1, 24.0, 48.0):
        run = run_scenario(SCENARIOS / "jan21-central.yaml", overrides=[f"parameters.motor.V_supply={bus}"])
        summary, statistics = run.summary, run.metadata["statistics"]
        per_step = statistics["rhs"] / max(summary["steps_executed"], 1)
        print(
            f"{bus:12.1f} {summary['peak_torque_Nm']:18.3f} {summary['max_tracking_error_deg']:16.4f} "
            f"{1e3 * summary['settling_time_s']['max']:14.1f} {per_step:9.0f}"
        )


def ring_decay_table() -> None:
    print("jan21-paper-literal: the torque's ring after the first step, by current-loop gain (V_supply = 3.1 V)")
    print(f"{'K_current [V/A]':>15} {'bandwidth K/(2 pi L) [kHz]':>27} {'peak [N m]':>11} {'below 5 % after [s]':>20}")
    for gain in (25.0, 100.0, 400.0, 1000.0, 2600.0):
        overrides = ["window.duration=40", "output.step_detail=8", f"parameters.motor.K_current={gain}"]
        trace = run_scenario(SCENARIOS / "jan21-paper-literal.yaml", overrides=overrides).trace
        time, torque, step = (trace[c].to_numpy() for c in ("time", "motor.tau", "step_index"))
        first = np.flatnonzero(np.diff(step) != 0)[0] + 1
        after = (time > time[first]) & (time < time[first] + 8.0)
        peak = np.abs(torque[after]).max()
        ringing = np.flatnonzero(after & (np.abs(torque) > 0.05 * peak))
        print(
            f"{gain:15.0f} {gain / (2e3 * np.pi * 1.8e-3):27.1f} {peak:11.3f} {time[ringing[-1]] - time[first]:20.2f}"
        )


if __name__ == "__main__":
    bus_voltage_table()
    print()
    ring_decay_table()
