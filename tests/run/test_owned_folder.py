"""A run owns its output folder (issue 22, items 2, 4, 5): a lock held for the run's life, a
manifest of the files heliostep wrote (only those are removed or replaced), the results swapped in,
and no output folder picked by accident (``--out ""``, path-like scenario names).

Real runs of the shipped scenarios (real FMUs, real CVODE) through ``heliostep.cli.main`` or in a
subprocess, with real signals.
"""

from __future__ import annotations

import json
import signal
import subprocess
import time
from pathlib import Path

import pytest

from heliostep.cli import main
from heliostep.paths import scenarios_dir
from heliostep.results.output.folder import LOCK_NAME, MANIFEST_NAME
from heliostep.results.trace.files import read_trace
from heliostep_process import five_day_scenario, popen_heliostep

SCENARIO = str(scenarios_dir() / "jan21-central.yaml")
SHORT = ["--set", "window.duration=20"]
#: Every figure a run with plots draws: the paper's Figs. 8-14 and the power on the tube.
FIGURES = {
    "fig08_panel_angle_ref.png",
    "fig09_rotor_angle_ref.png",
    "fig10_phase_currents.png",
    "fig11_torque.png",
    "fig12_rotor_angle.png",
    "fig13_panel_tracking.png",
    "fig14_torque_zoom.png",
    "power_on_tube.png",
}


def _manifest(out: Path) -> dict:
    return json.loads((out / MANIFEST_NAME).read_text())


def _wait_for(condition, process: subprocess.Popen, what: str, timeout: float = 60.0) -> None:
    deadline = time.monotonic() + timeout
    while not condition():
        assert process.poll() is None, process.communicate()
        assert time.monotonic() < deadline, what
        time.sleep(0.01)


def test_the_manifest_lists_every_file_written_and_a_rerun_replaces_only_those(tmp_path, fmu_paths, capsys):
    out = tmp_path / "out"
    assert main(["run", SCENARIO, "--out", str(out), *SHORT]) == 0
    files = {p.name for p in out.iterdir()}
    manifest = _manifest(out)
    assert manifest["state"] == "complete"
    # every file written, every figure kind among them (the power on the tube too), and nothing else
    assert set(manifest["files"]) == files - {MANIFEST_NAME}
    assert FIGURES <= set(manifest["files"])
    assert {"trace.parquet", "trace.csv", "summary.json", "metadata.json"} <= set(manifest["files"])
    assert LOCK_NAME not in files  # released with the run
    (out / "fig01_mine.png").write_text("the user's figure")
    (out / "notes.txt").write_text("the user's notes")
    assert main(["run", SCENARIO, "--out", str(out), *SHORT, "--no-plots", "--no-csv"]) == 0
    # the earlier run's figures (power_on_tube.png too) and CSV are gone; the user's files stay
    assert sorted(p.name for p in out.iterdir()) == sorted(
        [MANIFEST_NAME, "fig01_mine.png", "notes.txt", "metadata.json", "summary.json", "trace.parquet"]
    )
    assert (out / "fig01_mine.png").read_text() == "the user's figure"
    assert set(_manifest(out)["files"]) == {"metadata.json", "summary.json", "trace.parquet"}


@pytest.mark.parametrize("name", ["summary.json", "trace.parquet", "fig11_torque.png", "power_on_tube.png"])
def test_a_file_heliostep_did_not_write_is_never_replaced(name, tmp_path, fmu_paths, capsys):
    out = tmp_path / "out"
    out.mkdir()
    (out / name).write_text("the user's own")
    started = time.monotonic()
    assert main(["run", SCENARIO, "--out", str(out), *SHORT]) == 2
    err = capsys.readouterr().err
    assert name in err and MANIFEST_NAME in err and "Traceback" not in err
    assert time.monotonic() - started < 30  # refused before simulating: nothing else was written
    assert sorted(p.name for p in out.iterdir()) == [name]
    assert (out / name).read_text() == "the user's own"


def test_empty_out_is_refused(tmp_path, fmu_paths, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main(["run", SCENARIO, "--out", "", *SHORT]) == 2
    assert "--out: empty" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []  # not the current folder


@pytest.mark.parametrize("name", ["/tmp/heliostep-abs", ".", "..", "a/b", "a\\b", "../up"])
def test_a_scenario_name_that_is_a_path_is_refused_naming_the_key(name, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main(["run", SCENARIO, "--set", f"name={name}", *SHORT]) == 2
    err = capsys.readouterr().err
    assert "name:" in err and "one folder name" in err and "Traceback" not in err
    assert list(tmp_path.iterdir()) == []  # no out/ made


def test_a_second_run_into_a_held_folder_is_refused_naming_the_holder(tmp_path, fmu_paths, capsys):
    out = tmp_path / "out"
    first = popen_heliostep(["run", str(five_day_scenario(tmp_path)), "--out", str(out)])
    try:
        _wait_for(lambda: list(out.glob(".heliostep-tmp-*-trace.parquet")), first, "the first run did not start")
        holder = json.loads((out / LOCK_NAME).read_text())
        assert holder["pid"] == first.pid and "five-days.yaml" in holder["command"]
        assert main(["run", SCENARIO, "--out", str(out), *SHORT]) == 2
        err = capsys.readouterr().err
        assert f"in use by another heliostep run (pid {first.pid}" in err and "five-days.yaml" in err
        # the first run's streaming trace is untouched: it still ends with the trace so far
        first.send_signal(signal.SIGINT)
        _, stderr = first.communicate(timeout=60)
        assert first.returncode == 130, stderr
    finally:
        if first.poll() is None:
            first.kill()
            first.communicate()
    summary = json.loads((out / "summary.json").read_text())
    trace, meta = read_trace(out / "trace.parquet")
    # the trace so far is kept, all of it (how far the first run got depends on the machine's load)
    assert summary["reason"] == "interrupted" and summary["rows"] == len(trace) > 1
    assert trace["time"].iloc[-1] == pytest.approx(summary["time_reached_s"])
    assert not (out / LOCK_NAME).exists()


def test_a_symbolic_link_where_the_lock_goes_is_refused_and_its_target_untouched(tmp_path, fmu_paths, capsys):
    """A link planted as ``out/.heliostep-lock`` would have the lock's record written into its target (a
    user's file outside ``--out``): the run is refused before any simulation, naming the link, and the
    target keeps its bytes."""
    target = tmp_path / "important.txt"
    target.write_text("a user's own words\n")
    out = tmp_path / "out"
    out.mkdir()
    (out / LOCK_NAME).symlink_to(target)
    assert main(["run", SCENARIO, "--out", str(out), *SHORT, "--no-plots"]) == 2
    error = capsys.readouterr().err
    assert "symbolic link" in error and LOCK_NAME in error, error
    assert target.read_text() == "a user's own words\n"
    assert {p.name for p in out.iterdir()} == {LOCK_NAME} and (out / LOCK_NAME).is_symlink()


def test_the_lock_of_a_killed_run_is_taken_over_and_its_leftovers_removed(tmp_path, fmu_paths, capsys):
    out = tmp_path / "out"
    first = popen_heliostep(["run", str(five_day_scenario(tmp_path)), "--out", str(out)])
    _wait_for(lambda: list(out.glob(".heliostep-tmp-*-trace.parquet")), first, "the first run did not start")
    first.send_signal(signal.SIGKILL)  # no clean-up at all: the lock file and the stream stay
    first.communicate()
    assert json.loads((out / LOCK_NAME).read_text())["pid"] == first.pid
    assert list(out.glob(".heliostep-tmp-*"))
    assert main(["run", SCENARIO, "--out", str(out), *SHORT, "--no-plots"]) == 0
    assert sorted(p.name for p in out.iterdir()) == sorted(
        [MANIFEST_NAME, "metadata.json", "summary.json", "trace.csv", "trace.parquet"]
    )
    assert json.loads((out / "summary.json").read_text())["complete"] is True


def _one_run(out: Path) -> set[str]:
    """The folder holds one run's files: every file is in the manifest (state complete) and the
    trace, summary.json and metadata.json say the same (complete or not, time reached, rows)."""
    manifest = _manifest(out)
    assert manifest["state"] == "complete"
    assert {p.name for p in out.iterdir()} - {MANIFEST_NAME} == set(manifest["files"])
    summary = json.loads((out / "summary.json").read_text())
    metadata = json.loads((out / "metadata.json").read_text())
    trace, meta = read_trace(out / "trace.parquet")
    assert summary["complete"] is metadata["complete"] is (meta["complete"] == "true")
    assert summary["rows"] == len(trace)
    assert metadata["scenario"]["name"] == meta["scenario"]
    return set(manifest["files"])


def test_a_second_ctrl_c_between_the_simulation_and_the_writing_leaves_no_temporary(tmp_path, fmu_paths, monkeypatch):
    """The second stop signal can land anywhere, e.g. while the stop is reported, after the streamed
    trace is finished and before the writing's own ``try`` (there the stream,
    ``.heliostep-tmp-*-trace.parquet``, was left beside the old run): raised there, the old run
    stays whole and nothing temporary is left."""
    import heliostep.cli.run as cli_run
    from heliostep.cli.signals import ForcedStop

    out = tmp_path / "out"
    assert main(["run", SCENARIO, "--out", str(out), *SHORT, "--no-plots"]) == 0
    before = {p.name: p.read_bytes() for p in out.iterdir()}

    def second_signal(result):  # (where the stop is reported and its warnings printed)
        assert list(out.glob(".heliostep-tmp-*-trace.parquet"))  # the stream (over an hour), finished
        raise ForcedStop(signal.SIGINT)

    monkeypatch.setattr(cli_run, "_warn", second_signal)
    assert main(["run", SCENARIO, "--out", str(out), "--set", "window.duration=3700", "--no-plots"]) == 130
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before  # the old run, whole; nothing beside it


@pytest.mark.parametrize("gap", [0.0, 0.2])
def test_a_double_ctrl_c_while_a_rerun_writes_leaves_one_run_never_old_beside_new(gap, tmp_path, fmu_paths):
    out = tmp_path / "out"
    assert main(["run", SCENARIO, "--out", str(out), *SHORT]) == 0  # the old run, complete, with figures
    old_rows = json.loads((out / "summary.json").read_text())["rows"]
    process = popen_heliostep(["run", str(five_day_scenario(tmp_path)), "--out", str(out), "--csv"])
    _wait_for(lambda: list(out.glob(".heliostep-tmp-*-trace.parquet")), process, "the rerun did not start")
    time.sleep(1.0)
    process.send_signal(signal.SIGINT)  # stop: the rerun writes its trace so far (and a CSV of it)
    time.sleep(gap)
    process.send_signal(signal.SIGINT)  # and again, while it writes
    _, stderr = process.communicate(timeout=60)
    assert process.returncode == 130 and "Traceback" not in stderr, stderr
    _one_run(out)
    summary = json.loads((out / "summary.json").read_text())
    if summary["rows"] == old_rows:  # the old run, whole (figures too)
        assert summary["complete"] is True and FIGURES <= {p.name for p in out.iterdir()}
    else:  # the new run's trace so far, no old figure beside it
        assert summary["reason"] == "interrupted" and not FIGURES & {p.name for p in out.iterdir()}
    assert not list(out.glob(".heliostep-tmp-*")) and not (out / LOCK_NAME).exists()
