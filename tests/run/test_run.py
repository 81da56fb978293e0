"""run_scenario and 'heliostep run': the paper's case end to end, outputs, variants, bad input."""

import hashlib
import json
import os
import time
from pathlib import Path

import numpy as np
import pytest

from heliostep.cli import main
from heliostep.paths import scenarios_dir
from heliostep.results.trace.files import read_trace
from heliostep.run import RunFailed, run_scenario

SCENARIOS = scenarios_dir()
STEP = np.pi / 100  # 1.8 deg, Table 3
PINION_RADIUS, LEVER_ARM = 2.5e-3, 0.3  # Table 2
RATED_CURRENT, PHASE_RESISTANCE = 5.5, 0.1  # Table 3
TORQUE_CONSTANT, TEETH, LOOP_GAIN = 0.5, 50, 100  # Table 3 k_e, N_c; the current loop's K [V/A]
PANEL_INERTIA, ROTOR_INERTIA = 3.37, 1.4e-4  # Table 2 J_p; NEMA 34 rotor (models/PanelMechanics.mo)
DRIVE_FRICTION = 0.08  # Coulomb friction on the motor shaft T_c (models/PanelMechanics.mo)


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


def _since_last_step(run) -> np.ndarray:
    since_step = run.trace["time"].to_numpy()[:, None] - run.inputs.schedule.times[None, :]
    since_step[since_step < 0] = np.inf
    return since_step.min(axis=1)


def _ring_down_bound(panel_angle: float) -> float:
    """Longest time [s] a step can ring with Coulomb friction alone (no damping counted): the
    amplitude falls by 4 T_c / k per period from at most one step, k = k_e I N_c the detent
    stiffness, the period 2 pi sqrt(J / k) with J = J_m + J_p / g^2 on the motor shaft."""
    stiffness = TORQUE_CONSTANT * RATED_CURRENT * TEETH
    ratio = LEVER_ARM / (PINION_RADIUS * np.cos(panel_angle) ** 2)  # [paper], eq. 15
    inertia = ROTOR_INERTIA + PANEL_INERTIA / ratio**2
    periods = STEP / (4 * DRIVE_FRICTION / stiffness)
    return periods * 2 * np.pi * np.sqrt(inertia / stiffness)


def test_paper_case_torque_is_zero_while_idle(paper_run):
    # once a step has rung down (Coulomb friction stops it within _ring_down_bound, ~0.14 s)
    # the rotor rests in its detent: no torque but what friction can hold
    ring_down = _ring_down_bound(paper_run.trace["panel_angle_ref"].mean())
    assert 0.05 < ring_down < 0.2
    idle = _since_last_step(paper_run) > ring_down
    assert idle.sum() > 1000
    peak = np.abs(paper_run.trace["motor.tau"]).max()
    assert np.abs(paper_run.trace.loc[idle, "motor.tau"]).max() < 0.01 * peak


def test_paper_case_tracking_error_is_half_a_panel_step(paper_run):
    # stepping at the half-step midpoints keeps the settled error within half the panel motion
    # of one rotor step; while a step rings the rotor can overshoot its new detent by at most
    # the step it fell from (friction and back-EMF only take energy out): 1.5 panel steps
    panel_step = np.degrees(_panel_step(paper_run.trace["panel_angle_ref"].mean()))
    settled = _since_last_step(paper_run) > _ring_down_bound(paper_run.trace["panel_angle_ref"].mean())
    settled_error = np.degrees(np.abs(paper_run.trace.loc[settled, "panel_angle_error"])).max()
    assert 0.45 * panel_step < settled_error < 0.6 * panel_step
    assert settled_error <= paper_run.summary["max_tracking_error_deg"] < 1.5 * panel_step


def test_reach_trigger_doubles_the_error_to_one_panel_step(fmu_paths):
    run = run_scenario(SCENARIOS / "jan21-central.yaml", overrides=["sequencer.trigger=reach", "window.duration=60"])
    panel_step = np.degrees(_panel_step(run.trace["panel_angle_ref"].mean()))
    assert 0.95 * panel_step < run.summary["max_tracking_error_deg"] < 1.1 * panel_step


def test_paper_case_energy_is_the_holding_loss(paper_run):
    # one phase always carries K I / (K + R) (the averaged chopper's steady state): R i^2 per second
    current = 100 * RATED_CURRENT / (100 + PHASE_RESISTANCE)
    holding = PHASE_RESISTANCE * current**2 * paper_run.summary["duration_s"]
    assert paper_run.summary["electrical_energy_J"] == pytest.approx(holding, rel=0.01)
    # the loop holds K I / (K + R) < I; while a step rings, the back-EMF k_e omega (at most, per
    # phase) pushes the current by at most k_e omega / (K + R) more
    omega = np.abs(paper_run.trace["mechanics.omega"]).max()
    assert paper_run.summary["peak_phase_current_A"] <= RATED_CURRENT + TORQUE_CONSTANT * omega / (
        LOOP_GAIN + PHASE_RESISTANCE
    )


def test_run_command_writes_trace_summary_metadata_and_plots(tmp_path, fmu_paths, capsys):
    out = tmp_path / "run"
    status = main(["run", str(SCENARIOS / "jan21-central.yaml"), "--out", str(out), "--set", "window.duration=30"])
    assert status == 0
    assert "jan21-central: complete" in capsys.readouterr().out
    for name in (
        "trace.parquet",
        "trace.csv",
        "summary.json",
        "metadata.json",
        "fig08_panel_angle_ref.png",
        "fig13_panel_tracking.png",
    ):
        assert (out / name).stat().st_size > 0, name
    trace, meta = read_trace(out / "trace.parquet")
    assert meta["complete"] == "true" and meta["unit.motor.tau"] == "N.m"
    csv_trace, _ = read_trace(out / "trace.csv")
    np.testing.assert_array_equal(csv_trace["motor.tau"], trace["motor.tau"])
    summary = json.loads((out / "summary.json").read_text())
    for key in (
        "max_tracking_error_deg",
        "rms_tracking_error_deg",
        "peak_torque_Nm",
        "peak_phase_current_A",
        "electrical_energy_J",
        "steps_commanded",
        "steps_executed",
        "missed_steps",
        "settling_time_s",
    ):
        assert key in summary
    metadata = json.loads((out / "metadata.json").read_text())
    motor = metadata["fmus"]["motor"]
    assert motor["sha256"] == hashlib.sha256(Path(motor["path"]).read_bytes()).hexdigest()
    assert metadata["scenario"]["window"]["duration"] == 30


def test_the_figures_are_reported_before_the_plots_are_drawn(tmp_path, fmu_paths):
    """issue #26: the command line prints a run's figures once trace and records are written, then draws."""
    run = run_scenario(SCENARIOS / "jan21-central.yaml", overrides=["window.duration=30"])
    seen = {}

    def before_figures():
        seen["files"] = sorted(path.name for path in (tmp_path / "run").iterdir())

    written = run.write(tmp_path / "run", before_figures=before_figures)
    assert {"summary.json", "metadata.json", "trace.parquet"} <= set(seen["files"])
    assert not [name for name in seen["files"] if name.endswith(".png")]  # no figure drawn yet
    assert [name for name in written if name.endswith(".png")]  # then every figure


def test_variant_swap_is_one_set(fmu_paths):
    run = run_scenario(
        SCENARIOS / "jan21-central.yaml", overrides=["fmus.motor=StepperMotorIdealCurrent", "window.duration=30"]
    )
    assert run.metadata["fmus"]["motor"]["path"].endswith("StepperMotorIdealCurrent.fmu")
    # the lagged currents reach their references exactly (no proportional-loop offset)
    assert run.summary["peak_phase_current_A"] == pytest.approx(RATED_CURRENT, rel=1e-6)


def test_weak_motor_misses_steps_and_says_so(fmu_paths):
    run = run_scenario(SCENARIOS / "jan21-weak-motor.yaml", overrides=["window.duration=60"])
    summary, outcomes = run.summary, run.metadata["solution_figures"]["step_outcomes"]
    assert summary["steps_commanded"] == len(outcomes) >= 3
    # at every step the wind pushes the 2 A rotor back by one electrical period (4 full steps):
    # each step moves it by +1 - 4 = -3 increments, so every step is missed and 4 are lost per step
    assert [o["move_steps"] for o in outcomes] == pytest.approx([-3.0] * len(outcomes), abs=0.05)
    assert summary["missed_steps"] == summary["steps_commanded"] and summary["steps_executed"] == 0
    assert summary["steps_lost"] == 4 * summary["steps_commanded"]


@pytest.mark.parametrize("scenario", ["jan21-central.yaml", "jan21-weak-motor.yaml"])
def test_streamed_figures_equal_the_figures_of_every_row(fmu_paths, monkeypatch, scenario):
    """The recorder's running figures (memory bounded by one step interval) are those that the
    definitions give on all the rows it was shown, kept and assembled as a trace."""
    import heliostep.results.figures.run_figures as figures_module
    from figures_oracle import solution_figures
    from heliostep.results.figures.summary import SolutionRecorder
    from heliostep.results.trace.frame import assemble_trace

    recorders = []

    class Keeping(SolutionRecorder):
        def __init__(self, *args, **kwargs):
            super().__init__(*args, block=7, **kwargs)  # small blocks: steps cut across blocks
            self.kept = []
            recorders.append(self)

        def __call__(self, row):
            self.kept.append(np.array(row, dtype=float))
            super().__call__(row)

    monkeypatch.setattr(figures_module, "SolutionRecorder", Keeping)
    run = run_scenario(SCENARIOS / scenario, overrides=["window.duration=60"])
    recorder = recorders[0]
    import pandas as pd

    frame = pd.DataFrame(np.vstack(recorder.kept), columns=recorder.columns)
    assert recorder.unordered == 0 and np.all(np.diff(frame["time"].to_numpy()) >= 0)
    expected = solution_figures(assemble_trace(frame, run.inputs, run.metadata["roles"]), run.metadata)
    streamed = run.metadata["solution_figures"]
    assert set(streamed) == set(expected)
    for key in (
        "max_tracking_error_deg",
        "rms_tracking_error_deg",
        "peak_torque_Nm",
        "peak_phase_current_A",
        "electrical_energy_J",
        "final_lag_steps",
        "end_time_s",
        "error_integral_deg_s",
    ):
        assert streamed[key] == pytest.approx(expected[key], rel=1e-9), key
    assert streamed["error_integral_at_steps_deg_s"] == pytest.approx(
        expected["error_integral_at_steps_deg_s"], rel=1e-9, abs=1e-12
    )
    assert streamed["error_extremes_deg"] == expected["error_extremes_deg"]  # the same rows chosen
    assert streamed["error_sq_integral_deg2_s"] == pytest.approx(expected["error_sq_integral_deg2_s"], rel=1e-9)
    assert streamed["error_sq_integral_at_steps_deg2_s"] == pytest.approx(
        expected["error_sq_integral_at_steps_deg2_s"], rel=1e-9, abs=1e-15
    )
    for key in ("missed_steps", "steps_executed", "missed_step_times_s", "steps_lost", "solution_rows"):
        assert streamed[key] == expected[key], key
    for got, want in zip(streamed["step_outcomes"], expected["step_outcomes"], strict=True):
        assert got["missed"] == want["missed"] and got["move_steps"] == pytest.approx(want["move_steps"], rel=1e-9)
        assert (got["settling_s"] is None) == (want["settling_s"] is None)
        if want["settling_s"] is not None:
            assert got["settling_s"] == pytest.approx(want["settling_s"], rel=1e-9)
    # memory: the rotor rows held never exceed those of one step interval (the longest one)
    edges = np.searchsorted(frame["time"].to_numpy(), run.inputs.schedule.times, side="left")
    longest = int(np.max(np.diff(np.concatenate([edges, [len(frame)]])))) + 1
    assert 0 < recorder.max_held <= longest < len(frame) / 2


@pytest.mark.parametrize(
    "override, message",
    [
        ("fmus.motor=NoSuchMotor", "jan21-central.yaml: fmus.motor: unknown FMU variant 'NoSuchMotor'"),
        ("fmus.motor=missing/motor.fmu", "jan21-central.yaml: fmus.motor: FMU file not found"),
        ("parameters.motor.Rxx=3", "has no parameter 'Rxx'"),
        ("connections=[[motor.tau, mechanics.torque]]", "has no variable 'torque'"),
        (
            "connections=[[motor.power, mechanics.tau], [mechanics.theta, motor.theta], "
            "[mechanics.omega, motor.omega]]",
            "units differ",
        ),
        ("sequencer.mode=wave", "sequencer.mode"),
    ],
)
def test_bad_input_is_a_clear_error_and_exit_status_2(tmp_path, fmu_paths, capsys, override, message):
    out = tmp_path / "out"
    status = main(["run", str(SCENARIOS / "jan21-central.yaml"), "--out", str(out), "--set", override])
    assert status == 2
    err = capsys.readouterr().err
    assert message in err and "simulation failed" not in err
    assert not out.exists()  # no empty or INCOMPLETE folder left behind


def test_failure_mid_run_writes_the_trace_so_far_marked_incomplete(tmp_path, fmu_paths, capsys):
    args = [
        "run",
        str(SCENARIOS / "jan21-central.yaml"),
        "--out",
        str(tmp_path),
        "--no-plots",
        "--set",
        "solver.max_num_steps=40",
    ]
    assert main(args) == 1
    assert "simulation failed at t =" in capsys.readouterr().err
    trace, meta = read_trace(tmp_path / "trace.parquet")
    assert meta["complete"] == "false" and "simulation failed" in meta["error"]
    assert 9 < trace["time"].max() < 300  # it failed at the first step, at about 9.4 s
    assert json.loads((tmp_path / "summary.json").read_text())["complete"] is False
    with pytest.raises(RunFailed) as failure:
        run_scenario(SCENARIOS / "jan21-central.yaml", overrides=["solver.max_num_steps=40"])
    assert not failure.value.result.complete and len(failure.value.result.trace) > 0


SHORT = ["--set", "window.duration=2", "--no-plots"]


@pytest.mark.parametrize(
    "make_out",
    [
        lambda tmp: tmp / "a-file" / "out",  # a parent is a regular file (refused even to root)
        lambda tmp: tmp / "a-file",  # the --out itself is a file
    ],
)
def test_unusable_out_folder_is_refused_before_simulating(tmp_path, fmu_paths, capsys, make_out):
    (tmp_path / "a-file").write_text("not a folder")
    out = make_out(tmp_path)
    started = time.perf_counter()
    status = main(
        [
            "run",
            str(SCENARIOS / "jan21-day.yaml"),
            "--out",
            str(out),
            "--set",
            "window.end=null",
            "--set",
            "window.duration=864000",
        ]
    )  # ten days: a run of about 20 s if started
    assert status == 2 and time.perf_counter() - started < 5
    err = capsys.readouterr().err
    assert str(out) in err and "Traceback" not in err


def test_out_folder_that_cannot_be_written_is_refused(tmp_path, fmu_paths, capsys, monkeypatch):
    import builtins

    out = tmp_path / "ro"

    def refusing(real):
        def refusing_open(file, *args, **kwargs):  # root ignores chmod: refuse the probe instead
            if str(file).startswith(str(out)):
                raise PermissionError(13, "Permission denied", str(file))
            return real(file, *args, **kwargs)

        return refusing_open

    monkeypatch.setattr(builtins, "open", refusing(builtins.open))
    monkeypatch.setattr(os, "open", refusing(os.open))
    status = main(["run", str(SCENARIOS / "jan21-central.yaml"), "--out", str(out), *SHORT])
    assert status == 2
    assert f"--out {out}: the output folder is not writable" in capsys.readouterr().err


def test_write_failure_says_where_the_result_could_not_go(tmp_path, fmu_paths, capsys, monkeypatch):
    import heliostep.results.output.run_files as run_module

    out = tmp_path / "out"
    real = run_module.write_trace

    def full_disk(df, path, metadata=None):
        if out in Path(path).parents:  # into --out (its staging folder), not elsewhere
            raise OSError(28, "No space left on device")
        return real(df, path, metadata)

    monkeypatch.setattr(run_module, "write_trace", full_disk)
    monkeypatch.setenv("TMPDIR", str(tmp_path / "tmp"))
    (tmp_path / "tmp").mkdir()
    import tempfile

    monkeypatch.setattr(tempfile, "tempdir", None)
    assert main(["run", str(SCENARIOS / "jan21-central.yaml"), "--out", str(out), *SHORT]) == 1
    err = capsys.readouterr().err
    assert f"could not write the results to {out}" in err and "No space left" in err
    rescued = next((tmp_path / "tmp").glob("heliostep-jan21-central-*"))
    assert f"written to {rescued} instead" in err
    assert read_trace(rescued / "trace.parquet")[1]["complete"] == "true"
    assert not [p for p in out.iterdir() if p.name != "metadata.json"] or not (out / "trace.parquet").exists()


def test_interrupted_write_leaves_no_file_claiming_completeness(tmp_path, fmu_paths, monkeypatch):
    import heliostep.results.output.run_files as run_module

    run = run_scenario(SCENARIOS / "jan21-central.yaml", overrides=["window.duration=2"])
    real = run_module.write_trace

    def killed_midway(df, path, metadata=None):
        real(df, path, metadata)
        with open(path, "r+b") as fh:  # cut mid-row, as a kill while writing would
            fh.truncate(Path(path).stat().st_size // 2)
        raise KeyboardInterrupt

    monkeypatch.setattr(run_module, "write_trace", killed_midway)
    out = tmp_path / "out"
    with pytest.raises(KeyboardInterrupt):
        run.write(out, plots=False)
    assert list(out.iterdir()) == []  # no trace, no temporary file: nothing claims to be complete
    # an earlier complete file stays whole when the next write is cut
    monkeypatch.setattr(run_module, "write_trace", real)
    run.write(out, plots=False)
    before = (out / "trace.csv").read_bytes()
    monkeypatch.setattr(run_module, "write_trace", killed_midway)
    with pytest.raises(KeyboardInterrupt):
        run.write(out, plots=False)
    assert (out / "trace.csv").read_bytes() == before
    assert not [p for p in out.iterdir() if p.name.startswith(".heliostep-tmp-")]


def test_rerun_removes_stale_files_of_its_own_kinds_only(tmp_path, fmu_paths, capsys):
    out = tmp_path / "out"
    out.mkdir()
    for name in ("fig11_torque.png", "trace.csv", ".heliostep-tmp-abc-trace.parquet"):
        (out / name).write_text("stale")
    # an earlier run's files are those its manifest lists (a leftover temporary file is heliostep's by its name)
    stale = {"size": 5, "sha256": hashlib.sha256(b"stale").hexdigest()}  # as heliostep records its files
    listed = {"fig11_torque.png": stale, "trace.csv": stale}
    (out / ".heliostep-manifest.json").write_text(json.dumps({"files": listed}))
    (out / "mine.png").write_text("the user's")
    assert main(["run", str(SCENARIOS / "jan21-central.yaml"), "--out", str(out), "--no-csv", *SHORT]) == 0
    assert sorted(p.name for p in out.iterdir()) == [
        ".heliostep-manifest.json",
        "metadata.json",
        "mine.png",
        "summary.json",
        "trace.parquet",
    ]


def test_night_window_warns_and_says_so_in_the_summary(tmp_path, fmu_paths, capsys):
    out = tmp_path / "out"
    assert (
        main(["run", str(SCENARIOS / "jan21-central.yaml"), "--out", str(out), "--set", "window.start=22:00", *SHORT])
        == 0
    )
    assert "below the horizon" in capsys.readouterr().err
    summary = json.loads((out / "summary.json").read_text())
    assert summary["night"] is True and "below the horizon" in summary["warnings"][0]


def test_interrupted_summary_does_not_count_the_step_in_progress(fmu_paths):
    from heliostep.results.figures.summary import summary_at_cut, trace_summary

    run = run_scenario(SCENARIOS / "jan21-central.yaml", overrides=["window.duration=20"])
    steps = run.inputs.schedule.times
    cut = steps[0] + 0.001  # 1 ms into the first step: the rotor is on its way
    trace = run.trace[run.trace["time"] <= cut].reset_index(drop=True)
    metadata = {k: v for k, v in run.metadata.items() if k != "solution_figures"}  # those of the whole run
    summary, rows, solution = trace_summary(trace, metadata)
    naive = summary.figures()
    assert naive["missed_steps"] == 1  # what a summary of the cut trace alone would say
    fixed = summary_at_cut(summary, rows, solution).figures()
    assert fixed["missed_steps"] == 0 and fixed["steps_lost"] == 0 and fixed["steps_commanded"] == 0
    assert fixed["step_in_progress_at_cut_s"] == pytest.approx(steps[0])


def test_an_extra_fmu_that_terminates_early_makes_the_run_incomplete_and_says_so(tmp_path):
    # issue #24: an unconnected extra FMU (the mini Counter, which asks to terminate at t_stop = 9 s) used to
    # cut a 20 s window to 9 s while the run said "complete"; now the run is incomplete, reason terminated,
    # naming the FMU and the time, and the trace so far is kept
    from third_party_fmu import build_mini_fmu

    counter = build_mini_fmu("Counter", tmp_path)
    with pytest.raises(RunFailed) as failed:
        run_scenario(SCENARIOS / "jan21-central.yaml", overrides=["window.duration=20", f"fmus.counter={counter}"])
    result = failed.value.result
    assert not result.complete and result.reason == "terminated"
    assert result.time_reached == pytest.approx(9.0)
    assert "counter" in result.error and "t = 9 s" in result.error and "window's end at 20 s" in result.error
    assert result.trace["time"].max() == pytest.approx(9.0)
    assert result.metadata["terminated"]["time_s"] == pytest.approx(9.0)
