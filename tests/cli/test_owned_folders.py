"""Every command that writes a folder owns it (issue 22, item 5, for ``sweep``, ``geometry``,
``end-loss`` and ``field-light``; ``run``'s own: tests/run/test_owned_folder.py): the folder's lock
held for the command's life (a second command into it: exit 2 naming the holder), a manifest of the
files heliostep wrote (only those removed or replaced on a rerun), ``--out ""`` refused.

Real commands in subprocesses, real signals.
"""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from heliostep.paths import scenarios_dir
from heliostep.results.output.folder import LOCK_NAME, MANIFEST_NAME
from heliostep_process import popen_heliostep

SCENARIO = str(scenarios_dir() / "jan21-central.yaml")
#: The quickest call of each command (seconds), its --out given after these arguments.
QUICK = {
    "geometry": ["geometry", "--date", "2025-06-21", "--step", "1800"],
    "end-loss": ["end-loss", "--days", "172", "--end-length", "10", "--no-shading", "--step-minutes", "60"],
    "field-light": ["field-light", SCENARIO, "--days", "172", "--step-minutes", "60", "--no-shading"],
    "sweep": ["sweep", str(scenarios_dir() / "sweeps" / "smoke.yaml"), "--workers", "1"],
}


def _run(args: list[str], cwd: Path | None = None, timeout: float = 300) -> tuple[int, str, str]:
    process = popen_heliostep(args, cwd=cwd)
    out, err = process.communicate(timeout=timeout)
    return process.returncode, out, err


def _hold(folder: Path):
    """A process other than the test's holding ``folder``'s lock until killed (as a running command does)."""
    folder.mkdir(parents=True, exist_ok=True)
    code = (
        "import sys, time; from heliostep.results.output.folder import hold_folder\n"
        f"with hold_folder({str(folder)!r}, 'heliostep holder-of-the-test'):\n"
        "    print('held', flush=True); time.sleep(600)\n"
    )
    holder = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, text=True)
    assert holder.stdout.readline().strip() == "held", holder.communicate()
    return holder


@pytest.mark.parametrize("command", sorted(QUICK))
def test_empty_out_is_refused_and_nothing_written_in_the_current_folder(command, tmp_path):
    status, _, err = _run([*QUICK[command], "--out", ""], cwd=tmp_path)
    assert status == 2, err[-2000:]
    assert '--out: empty; name the output folder (e.g. "." for the current one)' in err
    assert "Traceback" not in err
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("command", sorted(QUICK))
def test_a_command_into_a_folder_held_by_another_is_refused_naming_the_holder(command, tmp_path):
    out = tmp_path / "out"
    holder = _hold(out)
    try:
        (out / "notes.txt").write_text("the user's")
        status, _, err = _run([*QUICK[command], "--out", str(out)], cwd=tmp_path)
    finally:
        holder.kill()
        holder.communicate()
    assert status == 2, err[-2000:]
    assert f"the folder is in use by another heliostep run (pid {holder.pid}: heliostep holder-of-the-test" in err
    assert sorted(p.name for p in out.iterdir()) == [LOCK_NAME, "notes.txt"]  # nothing written, nothing removed
    assert (out / "notes.txt").read_text() == "the user's"


def test_two_concurrent_end_loss_commands_one_refused_and_an_interrupt_leaves_no_staging(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    (out / "notes.txt").write_text("the user's")
    # the whole year with shading: minutes of work, still running when the second one comes
    first = popen_heliostep(["end-loss", "--end-length", "10", "--no-plots", "--out", str(out)])
    deadline = time.monotonic() + 120
    while not (out / LOCK_NAME).exists() or str(first.pid) not in (out / LOCK_NAME).read_text():
        assert first.poll() is None, first.communicate()
        assert time.monotonic() < deadline, "the first command did not take the lock"
        time.sleep(0.05)
    status, _, err = _run([*QUICK["end-loss"], "--out", str(out)])
    assert status == 2, err[-2000:]
    assert f"the folder is in use by another heliostep run (pid {first.pid}: " in err and "end-loss" in err
    assert first.poll() is None  # the first one goes on
    first.send_signal(signal.SIGINT)
    _, first_err = first.communicate(timeout=60)
    assert first.returncode == 130, first_err[-2000:]
    assert "Traceback" not in first_err
    # nothing half written, no staging folder, the lock released, the user's file untouched
    assert sorted(p.name for p in out.iterdir()) == ["notes.txt"]
    status, _, err = _run([*QUICK["end-loss"], "--out", str(out)])  # and the folder is free again
    assert status == 0, err[-2000:]
    assert sorted(p.name for p in out.iterdir()) == sorted(
        [MANIFEST_NAME, "end_loss_days.csv", "end_loss_year.png", "notes.txt"]
    )


def test_a_geometry_rerun_replaces_only_its_own_files_and_refuses_a_users_file_of_its_names(tmp_path):
    out = tmp_path / "out"
    status, _, err = _run([*QUICK["geometry"], "--paper-case", "--out", str(out)])
    assert status == 0, err[-2000:]
    ours = {
        "end_loss.csv",
        "end_loss.png",
        "two_axis_angles.csv",
        "two_axis_angles.png",
        "paper_case.csv",
        "paper_case_panel_angle.png",
        "paper_case_rotor_angle.png",
    }
    manifest = json.loads((out / MANIFEST_NAME).read_text())
    assert set(manifest["files"]) == ours and manifest["state"] == "complete"
    assert {p.name for p in out.iterdir()} == ours | {MANIFEST_NAME}
    (out / "fig01_mine.png").write_text("the user's figure")
    (out / "notes.txt").write_text("the user's notes")
    before = (out / "end_loss.csv").stat().st_mtime_ns
    status, _, err = _run([*QUICK["geometry"], "--out", str(out)])  # without the paper's case
    assert status == 0, err[-2000:]
    # the paper case's files of the first run are gone (they would describe another run); the user's stay
    mine = {"fig01_mine.png", "notes.txt"}
    assert {p.name for p in out.iterdir()} == ours - {n for n in ours if n.startswith("paper_case")} | mine | {
        MANIFEST_NAME
    }
    assert (out / "end_loss.csv").stat().st_mtime_ns != before  # replaced by the rerun's
    assert (out / "fig01_mine.png").read_text() == "the user's figure"
    # a file of one of the command's names that heliostep did not write: refused, never overwritten
    (out / "paper_case.csv").write_text("the user's table")
    status, _, err = _run([*QUICK["geometry"], "--paper-case", "--out", str(out)])
    assert status == 2, err[-2000:]
    assert f"paper_case.csv is not listed in {MANIFEST_NAME}" in err
    assert (out / "paper_case.csv").read_text() == "the user's table"


def test_a_field_light_rerun_removes_its_earlier_heatmaps_only(tmp_path):
    out = tmp_path / "out"
    two_days = ["field-light", SCENARIO, "--days", "172", "173", "--step-minutes", "60", "--no-shading"]
    status, _, err = _run([*two_days, "--out", str(out)])
    assert status == 0, err[-2000:]
    heatmaps = {"heatmap_light_lost_year.png", "heatmap_light_lost_fraction_year.png"}
    assert heatmaps <= {p.name for p in out.iterdir()}
    (out / "notes.txt").write_text("the user's")
    status, _, err = _run([*two_days, "--no-plots", "--out", str(out)])
    assert status == 0, err[-2000:]
    assert {p.name for p in out.iterdir()} == {"field_light_days.csv", MANIFEST_NAME, "notes.txt"}
