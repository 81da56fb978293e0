"""A trace streamed to Parquet row groups while simulating (long windows) equals the trace held in
memory; the master holds at most one sink block; a file being written claims nothing."""

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow.parquet as pq
import pytest

from heliostep.cli import main
from heliostep.cosim.fmi import read_fmu
from heliostep.cosim.master import Connection, CoSimulation, PiecewiseConstant, SimulationError
from heliostep.drive.sequencer import Sequencer
from heliostep.errors import InputError
from heliostep.paths import scenarios_dir
from heliostep.results.trace.files import copy_trace_to_csv, read_trace
from heliostep.run import RunFailed, RunOptions, run_scenario

SCENARIOS = scenarios_dir()
WINDOW = ["window.duration=20"]  # 2 steps of the paper's case: about 300 rows


@pytest.fixture(scope="module")
def held(fmu_paths):
    return run_scenario(SCENARIOS / "jan21-central.yaml", RunOptions(stream=False), overrides=WINDOW)


def test_streamed_parquet_equals_the_trace_held_in_memory(held, fmu_paths, tmp_path, monkeypatch):
    import heliostep.run.runner as run_module

    monkeypatch.setattr(run_module, "SINK_ROWS", 5)  # the master's blocks: 5 rows, cut anywhere
    rows_per_group = 23
    streamed = run_scenario(
        SCENARIOS / "jan21-central.yaml",
        RunOptions(stream=True, trace_dir=tmp_path, row_group_rows=rows_per_group),
        overrides=WINDOW,
    )
    assert streamed.held_trace is None and streamed.trace_file.parent == tmp_path
    n = len(held.trace)
    assert n > 10 * rows_per_group
    assert pq.ParquetFile(streamed.trace_file).num_row_groups == -(-n // rows_per_group)  # ceil
    trace, meta = read_trace(streamed.trace_file)
    pd.testing.assert_frame_equal(trace, held.trace, check_exact=True)  # every column, bit for bit
    # the step index at the two rows of a step instant: before, then after (blocks cut anywhere)
    time = trace["time"].to_numpy()
    first_step = held.inputs.schedule.times[0]
    at_step = np.flatnonzero(time == first_step)
    assert len(at_step) >= 2
    index = trace["step_index"].to_numpy()
    assert index[at_step[0]] == held.inputs.schedule.initial_index
    assert index[at_step[-1]] == held.inputs.schedule.indices[0]
    assert meta["complete"] == "true" and meta["unit.motor.tau"] == "N.m"
    # the figures: evaluated in chunks of 23 rows here, of all rows in the held run: equal to
    # rounding (bit for bit with the same chunks: tests/results/figures/test_run_figures.py)
    assert set(streamed.summary) == set(held.summary)
    # differences of two light energies (lost, stepping change) agree to the energies' rounding
    energy_rounding = 1e-12 * held.summary["light_energy_ideal_J"]
    for key, value in held.summary.items():
        if isinstance(value, float) and key.startswith(("light_lost", "light_stepping")) and key.endswith("_J"):
            assert streamed.summary[key] == pytest.approx(value, abs=energy_rounding), key
        elif isinstance(value, float) and key.startswith(("light_lost", "light_stepping")):  # their ratios
            assert streamed.summary[key] == pytest.approx(value, rel=1e-6, abs=1e-15), key
        elif isinstance(value, float):
            assert streamed.summary[key] == pytest.approx(value, rel=1e-12), key
        elif not isinstance(value, float):
            assert streamed.summary[key] == value, key
    # written into place by renaming; the CSV copy is made from the Parquet in batches
    out = tmp_path
    streamed.write(out, plots=False, csv=True)
    assert not [p for p in out.iterdir() if p.name.startswith(".heliostep-tmp-")]
    assert streamed.trace_file == out / "trace.parquet"
    csv_trace, csv_meta = read_trace(out / "trace.csv")  # its metadata from the metadata.json beside it
    pd.testing.assert_frame_equal(csv_trace, through_degrees(held.trace, csv_meta), check_exact=True)
    assert csv_meta == held.trace_metadata()


@pytest.mark.parametrize("block", [1, 2, 3, 7])
def test_trace_assembled_block_by_block_equals_the_whole(held, block):
    from heliostep.results.trace.frame import TraceAssembler

    derived = ["panel_angle_ref", "rotor_angle_ref", "step_index", "rotor_angle_cmd", "panel_angle_error"]
    master = held.trace.drop(columns=derived)
    assembler = TraceAssembler(held.inputs, held.metadata["roles"])
    parts = [assembler(master.iloc[k : k + block].reset_index(drop=True)) for k in range(0, len(master), block)]
    pd.testing.assert_frame_equal(pd.concat(parts, ignore_index=True), held.trace, check_exact=True)
    assert assembler.columns(list(master.columns)) == list(held.trace.columns)


def test_csv_copy_in_small_batches_equals_the_parquet(held, tmp_path):
    held.write(tmp_path, plots=False, csv=False)
    parquet = tmp_path / "trace.parquet"
    copy_trace_to_csv(parquet, tmp_path / "t.csv", batch_rows=7)
    trace, meta = read_trace(parquet)
    pd.testing.assert_frame_equal(read_trace(tmp_path / "t.csv")[0], through_degrees(trace, meta), check_exact=True)


def through_degrees(trace: pd.DataFrame, meta: dict[str, str]) -> pd.DataFrame:
    """``trace`` as its CSV reads back: every value bit for bit, but the angles (``rad``, ``rad/s``), which
    the CSV holds in degrees (each the shortest text of ``np.degrees``): ``np.radians`` of those."""
    out = trace.copy()
    for column in out.columns:
        unit = meta.get(f"unit.{column}", "")
        if unit == "rad" or unit.startswith("rad/"):
            out[column] = np.radians(np.degrees(out[column].to_numpy()))
    return out


def test_master_holds_at_most_one_block_of_the_sink(fmu_paths):
    drive = {"motor": read_fmu(fmu_paths["StepperMotor"]), "mechanics": read_fmu(fmu_paths["PanelMechanics"])}
    connections = [
        Connection("motor.tau", "mechanics.tau"),
        Connection("mechanics.theta", "motor.theta"),
        Connection("mechanics.omega", "motor.omega"),
    ]
    steps = np.array([0.05, 0.15, 0.25])
    i_a, i_b = Sequencer().reference_currents(np.array([0, 1, 2, 3]))
    inputs = [
        PiecewiseConstant("i_a_ref", "motor.i_a_ref", steps, i_a),
        PiecewiseConstant("i_b_ref", "motor.i_b_ref", steps, i_b),
    ]
    grid = np.round(np.arange(0.0, 0.3 + 1e-9, 1e-3), 12)
    whole = CoSimulation(drive, connections, inputs).simulate(0.0, 0.3, grid)
    # 301 grid rows and two rows at each of the 3 steps (before and after): rows = 301 + 3
    assert len(whole.trace) == len(grid) + len(steps)
    blocks = []
    result = CoSimulation(drive, connections, inputs).simulate(0.0, 0.3, grid, sink=blocks.append, sink_rows=16)
    assert len(result.trace) == 0 and list(result.trace.columns) == list(whole.trace.columns)
    assert max(len(b) for b in blocks) <= 16 and result.statistics["max_buffered_rows"] <= 16
    assert sum(len(b) for b in blocks) == len(whole.trace)
    np.testing.assert_array_equal(np.vstack(blocks), whole.trace.to_numpy())
    # interrupted: the rows so far reach the sink before the error is raised
    blocks.clear()
    calls = []
    with pytest.raises(SimulationError) as stopped:
        CoSimulation(drive, connections, inputs).simulate(
            0.0, 0.3, grid, sink=blocks.append, sink_rows=16, should_stop=lambda: calls.append(1) or len(calls) > 100
        )
    assert stopped.value.reason == "interrupted" and len(stopped.value.trace) == 0
    rows = np.vstack(blocks)
    assert rows[-1, 0] == pytest.approx(stopped.value.time) and 50 < len(rows) < len(whole.trace)
    np.testing.assert_array_equal(rows, whole.trace.to_numpy()[: len(rows)])


def test_interrupted_stream_is_written_marked_and_claims_nothing_while_written(fmu_paths, tmp_path):
    seen = []

    def should_stop():  # while simulating: the file being written has no footer, so no metadata
        files = list(tmp_path.glob(".heliostep-tmp-*-trace.parquet"))
        assert len(files) == 1
        with pytest.raises(InputError):
            read_trace(files[0])
        seen.append(1)
        return len(seen) > 2  # (asked between solver calls and blocks of solver steps)

    with pytest.raises(RunFailed) as failed:
        run_scenario(
            SCENARIOS / "jan21-central.yaml",
            RunOptions(stream=True, trace_dir=tmp_path, row_group_rows=10, should_stop=should_stop),
            overrides=WINDOW,
        )
    run = failed.value.result
    assert run.reason == "interrupted" and len(seen) == 3
    trace, meta = read_trace(run.trace_file)
    assert meta["complete"] == "false" and meta["reason"] == "interrupted"
    assert float(meta["time_reached"]) == run.time_reached == pytest.approx(trace["time"].iloc[-1])
    assert run.summary["rows"] == len(trace)
    run.write(tmp_path, plots=False, csv=False)
    files = sorted(p.name for p in tmp_path.iterdir() if p.name != ".heliostep-manifest.json")
    assert files == ["metadata.json", "summary.json", "trace.parquet"]
    assert json.loads((tmp_path / "summary.json").read_text())["complete"] is False


def test_long_window_streams_its_trace_and_draws_every_figure_from_the_file(fmu_paths, tmp_path):
    out = tmp_path / "out"
    assert (
        main(
            [
                "run",
                str(SCENARIOS / "jan21-central.yaml"),
                "--out",
                str(out),
                "--no-csv",
                "--set",
                "window.duration=3700",
                "--set",
                "output.interval=10",
            ]
        )
        == 0
    )
    names = sorted(p.name for p in out.iterdir() if p.name != ".heliostep-manifest.json")
    assert names == [
        "fig08_panel_angle_ref.png",
        "fig09_rotor_angle_ref.png",
        "fig10_phase_currents.png",
        "fig11_torque.png",
        "fig12_rotor_angle.png",
        "fig13_panel_tracking.png",
        "fig14_torque_zoom.png",
        "metadata.json",
        "power_on_tube.png",
        "summary.json",
        "trace.parquet",
    ]
    summary = json.loads((out / "summary.json").read_text())
    metadata = json.loads((out / "metadata.json").read_text())
    trace, meta = read_trace(out / "trace.parquet")
    assert meta["complete"] == "true" and summary["rows"] == len(trace)
    assert trace["time"].iloc[-1] == 3700.0
    # streamed: the master held at most its block of rows, not the window's
    assert metadata["statistics"]["max_buffered_rows"] <= 4096 < len(trace)


FULL_DISK_SCRIPT = """
import resource, sys
from pathlib import Path
from heliostep.paths import scenarios_dir
from heliostep.errors import RunFailure
from heliostep.run import RunFailed, RunOptions, run_scenario

out, limit = Path(sys.argv[1]), int(sys.argv[2])
resource.setrlimit(resource.RLIMIT_FSIZE, (limit, resource.RLIM_INFINITY))  # no file may grow past it
try:
    run_scenario(scenarios_dir() / "jan21-central.yaml", RunOptions(stream=True, trace_dir=out, row_group_rows=256),
                 overrides=["window.duration=600"])
except RunFailed as failed:
    result = failed.result
    print(result.trace_file, len(result.unwritten_trace))
    try:
        result.write(out, plots=False, csv=False)  # all the rows do not fit: nothing is swapped in
    except (OSError, RunFailure) as exc:  # TraceWriteError, a RunFailure: the file-size limit
        print("write failed:", exc)
    sys.exit(1)
"""


@pytest.mark.skipif(__import__("sys").platform == "win32", reason="RLIMIT_FSIZE needs a POSIX system")
def test_a_write_failing_mid_stream_keeps_the_row_groups_written(fmu_paths, tmp_path):
    """A real write failure (the process's file-size limit, EFBIG, as a full disk gives ENOSPC)
    part-way through the stream: the trace keeps every row group written before it, readable,
    marked complete: false / reason: failed, with the time it holds."""
    import subprocess
    import sys

    # bytes: inside a row group (256 rows each), placed so that the footer of the groups kept fits in what the
    # failed one leaves below the limit (the trace's compression sets where that is: 100 000, 125 000 and 170 000
    # do, 110 000 to 120 000 and 130 000 to 165 000 leave no room for it)
    limit = 125_000
    process = subprocess.run(
        [sys.executable, "-c", FULL_DISK_SCRIPT, str(tmp_path), str(limit)], capture_output=True, text=True, timeout=120
    )
    assert process.returncode == 1, process.stderr
    stream, unwritten = process.stdout.splitlines()[0].split()
    assert "write failed" in process.stdout and "File too large" in process.stdout
    held = run_scenario(SCENARIOS / "jan21-central.yaml", RunOptions(stream=False), overrides=["window.duration=600"])
    trace, meta = read_trace(stream)
    n = len(trace)
    assert 0 < n < len(held.trace) and n % 256 == 0  # whole row groups, and not all of them
    assert pq.ParquetFile(stream).num_row_groups == n // 256
    assert Path(stream).stat().st_size <= limit
    pd.testing.assert_frame_equal(trace, held.trace.iloc[:n], check_exact=True)  # the rows, bit for bit
    last = float(trace["time"].iloc[-1])
    assert meta["complete"] == "false" and meta["reason"] == "failed" and float(meta["time_reached"]) == last
    assert "could not write" in meta["error"] and "File too large" in meta["error"]
    # the rows computed after the file's last one were held in memory (for the rescue:
    # tests/cli/test_storage_failures.py), and the file says how many
    assert int(meta["rows_computed_after_this_file"]) == int(unwritten) > 0
    # the output folder: nothing swapped in, nothing claiming completeness; the stream is kept
    assert not (tmp_path / "trace.parquet").exists() and not (tmp_path / "summary.json").exists()
    assert [p for p in tmp_path.iterdir() if p.name.startswith(".heliostep-tmp-")] == [Path(stream)]
