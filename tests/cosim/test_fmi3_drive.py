"""The shipped drive built as FMI 3.0 FMUs (``NAME-fmi3``) co-simulated by the master beside the FMI 2.0
drive (issue #24): the same generated equations behind each standard's API, so the same trace."""

from __future__ import annotations

import numpy as np

from heliostep.paths import scenarios_dir
from heliostep.results.compare.tolerance import load_tolerances
from heliostep.results.compare.traces import compare_traces
from heliostep.run import run_scenario

WINDOW = ["window.duration=60"]  # two steps of the paper's case
FMI3 = ["fmus.motor=StepperMotor-fmi3", "fmus.mechanics=PanelMechanics-fmi3"]


def test_the_fmi3_drive_gives_the_fmi2_drives_run(fmu_paths):
    scenario = scenarios_dir() / "jan21-central.yaml"
    fmi2 = run_scenario(scenario, overrides=WINDOW)
    fmi3 = run_scenario(scenario, overrides=[*WINDOW, *FMI3])
    assert fmi3.metadata["fmus"]["motor"]["path"].endswith("StepperMotor-fmi3.fmu")
    assert fmi2.summary["steps_commanded"] == fmi3.summary["steps_commanded"] >= 2
    for column in ("motor.tau", "motor.i_a", "motor.i_b", "mechanics.theta", "mechanics.theta_p"):
        np.testing.assert_array_equal(fmi3.trace[column].to_numpy(), fmi2.trace[column].to_numpy())
    assert fmi3.summary["peak_torque_Nm"] == fmi2.summary["peak_torque_Nm"]
    # and inside the regression tubes of the shipped scenario (scenarios/regress-tolerances.yaml)
    tolerances = load_tolerances(scenarios_dir() / "regress-tolerances.yaml").for_scenario("jan21-central")
    verdict = compare_traces(fmi3.trace, fmi2.trace, tolerances)
    assert verdict.passed and len(verdict.signals) >= 5
