"""The two friction models of the panel mechanics side by side: the tanh-smoothed Coulomb friction of
``PanelMechanics`` (the default) and Karnopp's stick-slip friction of ``PanelMechanicsKarnopp``.

    .venv/bin/python benchmarks/friction_models.py

Runs each shipped scenario that uses ``PanelMechanics`` twice, the second time with
``fmus.mechanics=PanelMechanicsKarnopp``, and prints the figures a motor is sized by and the cost: peak
torque, max tracking error, settling, missed and lost steps, the rotor's final lag behind its detent (in
steps: where a stuck rotor rests), RHS evaluations per executed step and in all. Not a test (ten runs, one
of them a day: a few minutes).
"""

from __future__ import annotations

from heliostep.paths import scenarios_dir
from heliostep.run import RunOptions, run_scenario

SCENARIOS = ("jan21-central", "jan21-48v", "jan21-ideal-current", "jan21-weak-motor", "jan21-day")
MODELS = {"tanh": (), "Karnopp": ("fmus.mechanics=PanelMechanicsKarnopp",)}


def main() -> None:
    print(
        f"{'scenario':20} {'friction':8} {'peak [N m]':>10} {'max err [deg]':>13} {'settling [ms]':>13} "
        f"{'missed/lost':>11} {'final lag':>9} {'RHS/step':>8} {'RHS':>9}"
    )
    for name in SCENARIOS:
        for label, overrides in MODELS.items():
            run = run_scenario(scenarios_dir() / f"{name}.yaml", RunOptions(keep_trace=False), overrides=overrides)
            summary, rhs = run.summary, run.metadata["statistics"]["rhs"]
            settling = summary["settling_time_s"]["max"]
            settling_ms = f"{1e3 * settling:13.1f}" if settling is not None else f"{'-':>13}"
            print(
                f"{name:20} {label:8} {summary['peak_torque_Nm']:10.3f} {summary['max_tracking_error_deg']:13.4f} "
                f"{settling_ms} {summary['missed_steps']:>5}/{summary['steps_lost']:<5} "
                f"{summary['final_lag_steps']:9.4f} {rhs / max(summary['steps_executed'], 1):8.0f} {rhs:9d}"
            )


if __name__ == "__main__":
    main()
