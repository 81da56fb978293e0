"""run_scenario and 'heliostep run': the paper's case end to end, outputs, variants, bad input."""

import json
import hashlib
from pathlib import Path

import numpy as np
import pytest

from heliostep.paths import scenarios_dir
from heliostep.cli import main
from heliostep.run import RunFailed, run_scenario
from heliostep.results.trace_io import read_trace

SCENARIOS = scenarios_dir()
STEP = np.pi / 100  # 1.8 deg, Table 3
PINION_RADIUS, LEVER_ARM = 2.5e-3, 0.3  # Table 2
RATED_CURRENT, PHASE_RESISTANCE = 5.5, 0.1  # Table 3


@pytest.fixture(scope="module")
def paper_run(fmu_paths):
    return run_scenario(SCENARIOS / "jan21-central.yaml")


def _panel_step(panel_angle):
    """Panel rotation of one rotor step at a panel angle ([paper], eq. 14 solved for the panel)."""
    return np.arctan(np.tan(panel_angle) + PINION_RADIUS / LEVER_ARM * STEP) - panel_angle


def test_paper_case_executes_every_step_and_ends_on_the_last_command(paper_run):
    summary, trace = paper_run.summary, paper_run.trace
    assert summary["steps_commanded"] >= 10
    assert summary["steps_executed"] == summary["steps_commanded"] and summary["missed_steps"] == 0
    assert abs(trace["mechanics.theta"].iloc[-1] - trace["rotor_angle_cmd"].iloc[-1]) < STEP / 2


def test_paper_case_torque_is_zero_while_idle(paper_run):
    trace, steps = paper_run.trace, paper_run.inputs.schedule.times
    since_step = trace["time"].to_numpy()[:, None] - steps[None, :]
    since_step[since_step < 0] = np.inf
    idle = since_step.min(axis=1) > 0.1  # more than 100 ms after the latest step
    assert idle.sum() > 1000
    peak = np.abs(trace["motor.tau"]).max()
    assert np.abs(trace.loc[idle, "motor.tau"]).max() < 0.01 * peak


def test_paper_case_tracking_error_is_half_a_panel_step(paper_run):
    # stepping at the half-step midpoints keeps the error within half the panel motion of one
    # rotor step, plus the short lag of the step itself
    panel_step = np.degrees(_panel_step(paper_run.trace["panel_angle_ref"].mean()))
    assert 0.45 * panel_step < paper_run.summary["max_tracking_error_deg"] < 0.6 * panel_step


def test_reach_trigger_doubles_the_error_to_one_panel_step(fmu_paths):
    run = run_scenario(SCENARIOS / "jan21-central.yaml", ["sequencer.trigger=reach", "window.duration=60"])
    panel_step = np.degrees(_panel_step(run.trace["panel_angle_ref"].mean()))
    assert 0.95 * panel_step < run.summary["max_tracking_error_deg"] < 1.1 * panel_step


def test_paper_case_energy_is_the_holding_loss(paper_run):
    # one phase always carries K I / (K + R) (the averaged chopper's steady state): R i^2 per second
    current = 100 * RATED_CURRENT / (100 + PHASE_RESISTANCE)
    holding = PHASE_RESISTANCE * current**2 * paper_run.summary["duration_s"]
    assert paper_run.summary["electrical_energy_J"] == pytest.approx(holding, rel=0.01)
    assert paper_run.summary["peak_phase_current_A"] <= RATED_CURRENT


def test_run_command_writes_trace_summary_metadata_and_plots(tmp_path, fmu_paths, capsys):
    out = tmp_path / "run"
    status = main(["run", str(SCENARIOS / "jan21-central.yaml"), "--out", str(out),
                   "--set", "window.duration=30"])
    assert status == 0
    assert "jan21-central: complete" in capsys.readouterr().out
    for name in ("trace.parquet", "trace.csv", "summary.json", "metadata.json",
                 "fig08_panel_angle_ref.png", "fig13_panel_tracking.png"):
        assert (out / name).stat().st_size > 0, name
    trace, meta = read_trace(out / "trace.parquet")
    assert meta["complete"] == "true" and meta["unit.motor.tau"] == "N.m"
    csv_trace, _ = read_trace(out / "trace.csv")
    np.testing.assert_array_equal(csv_trace["motor.tau"], trace["motor.tau"])
    summary = json.loads((out / "summary.json").read_text())
    for key in ("max_tracking_error_deg", "rms_tracking_error_deg", "peak_torque_Nm", "peak_phase_current_A",
                "electrical_energy_J", "steps_commanded", "steps_executed", "missed_steps", "settling_time_s"):
        assert key in summary
    metadata = json.loads((out / "metadata.json").read_text())
    motor = metadata["fmus"]["motor"]
    assert motor["sha256"] == hashlib.sha256(Path(motor["path"]).read_bytes()).hexdigest()
    assert metadata["scenario"]["window"]["duration"] == 30


def test_variant_swap_is_one_set(fmu_paths):
    run = run_scenario(SCENARIOS / "jan21-central.yaml",
                       ["fmus.motor=StepperMotorIdealCurrent", "window.duration=30"])
    assert run.metadata["fmus"]["motor"]["path"].endswith("StepperMotorIdealCurrent.fmu")
    # the lagged currents reach their references exactly (no proportional-loop offset)
    assert run.summary["peak_phase_current_A"] == pytest.approx(RATED_CURRENT, rel=1e-6)


def test_weak_motor_misses_steps_and_says_so(fmu_paths):
    run = run_scenario(SCENARIOS / "jan21-weak-motor.yaml", ["window.duration=60"])
    assert run.summary["missed_steps"] > 0
    assert run.summary["steps_lost"] >= 4  # slips lose whole electrical cycles of 4 full steps


@pytest.mark.parametrize("override, message", [
    ("fmus.motor=NoSuchMotor", "unknown FMU variant 'NoSuchMotor'"),
    ("fmus.motor=missing/motor.fmu", "FMU file not found"),
    ("connections=[[motor.tau, mechanics.torque]]", "has no variable 'torque'"),
    ("connections=[[motor.power, mechanics.tau], [mechanics.theta, motor.theta], [mechanics.omega, motor.omega]]",
     "units differ"),
    ("sequencer.mode=wave", "sequencer.mode"),
])
def test_bad_input_is_a_clear_error_and_exit_status_2(tmp_path, fmu_paths, capsys, override, message):
    status = main(["run", str(SCENARIOS / "jan21-central.yaml"), "--out", str(tmp_path), "--set", override])
    assert status == 2
    assert message in capsys.readouterr().err


def test_failure_mid_run_writes_the_trace_so_far_marked_incomplete(tmp_path, fmu_paths, capsys):
    args = ["run", str(SCENARIOS / "jan21-central.yaml"), "--out", str(tmp_path), "--no-plots",
            "--set", "solver.max_num_steps=40"]
    assert main(args) == 1
    assert "simulation failed at t =" in capsys.readouterr().err
    trace, meta = read_trace(tmp_path / "trace.parquet")
    assert meta["complete"] == "false" and "simulation failed" in meta["error"]
    assert 9 < trace["time"].max() < 300  # it failed at the first step, at about 9.4 s
    assert json.loads((tmp_path / "summary.json").read_text())["complete"] is False
    with pytest.raises(RunFailed) as failure:
        run_scenario(SCENARIOS / "jan21-central.yaml", ["solver.max_num_steps=40"])
    assert not failure.value.result.complete and len(failure.value.result.trace) > 0
