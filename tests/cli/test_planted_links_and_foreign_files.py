"""Every command that writes refuses a symbolic link it did not make where it writes (exit 2, naming it, its
target untouched), and removes or replaces only files still as it wrote them (the manifest's size and sha256):
a listed file changed since, or listed by a manifest copied from elsewhere, is kept and named.

Real commands (``heliostep.cli.main`` or a subprocess), real FMUs, real files.
"""

from __future__ import annotations

import json
from pathlib import Path

from heliostep.cli import main
from heliostep.paths import scenarios_dir
from heliostep.results.output.folder import MANIFEST_NAME
from heliostep_process import popen_heliostep

SCENARIO = str(scenarios_dir() / "jan21-central.yaml")
SHORT = ["--set", "window.duration=20", "--no-plots"]
GEOMETRY = ["geometry", "--date", "2025-06-21", "--step", "1800"]
END_LOSS = ["end-loss", "--days", "172", "--end-length", "10", "--no-shading", "--step-minutes", "60"]
WORDS = "a user's own words\n"


def _target(tmp_path: Path) -> Path:
    target = tmp_path / "important.txt"
    target.write_text(WORDS)
    return target


def _run(args: list[str]) -> tuple[int, str]:
    process = popen_heliostep(args)
    _, err = process.communicate(timeout=300)
    return process.returncode, err


def test_run_refuses_a_link_planted_as_its_manifest(tmp_path, fmu_paths, capsys):
    target, out = _target(tmp_path), tmp_path / "out"
    out.mkdir()
    (out / MANIFEST_NAME).symlink_to(target)
    assert main(["run", SCENARIO, "--out", str(out), *SHORT]) == 2
    err = capsys.readouterr().err
    assert MANIFEST_NAME in err and "symbolic link" in err and "Traceback" not in err
    assert target.read_text() == WORDS and (out / MANIFEST_NAME).is_symlink()


def test_a_rerun_refuses_a_link_planted_over_a_file_of_the_earlier_run(tmp_path, fmu_paths, capsys):
    target, out = _target(tmp_path), tmp_path / "out"
    assert main(["run", SCENARIO, "--out", str(out), *SHORT]) == 0
    (out / "trace.csv").unlink()
    (out / "trace.csv").symlink_to(target)
    capsys.readouterr()
    assert main(["run", SCENARIO, "--out", str(out), *SHORT]) == 2
    err = capsys.readouterr().err
    assert "trace.csv is listed in" in err and "not as heliostep wrote it" in err, err
    assert target.read_text() == WORDS and (out / "trace.csv").is_symlink()


def test_a_run_keeps_and_names_a_users_file_a_copied_manifest_lists(tmp_path, fmu_paths, capsys):
    out = tmp_path / "out"
    out.mkdir()
    (out / "notes.txt").write_text(WORDS)
    manifest = {"files": {"notes.txt": {"size": 3, "sha256": "0" * 64}}, "state": "complete"}
    (out / MANIFEST_NAME).write_text(json.dumps(manifest))
    assert main(["run", SCENARIO, "--out", str(out), *SHORT]) == 0
    err = capsys.readouterr().err
    assert "kept notes.txt" in err
    assert (out / "notes.txt").read_text() == WORDS
    assert "notes.txt" not in json.loads((out / MANIFEST_NAME).read_text())["files"]


def test_a_run_refuses_to_overwrite_its_own_file_changed_since_naming_it_foreign(tmp_path, fmu_paths, capsys):
    out = tmp_path / "out"
    assert main(["run", SCENARIO, "--out", str(out), *SHORT]) == 0
    (out / "summary.json").write_text('{"edited": "by the user"}\n')
    capsys.readouterr()
    assert main(["run", SCENARIO, "--out", str(out), *SHORT]) == 2
    err = capsys.readouterr().err
    assert "summary.json is listed in" in err and "heliostep did not write it" in err, err
    assert (out / "summary.json").read_text() == '{"edited": "by the user"}\n'


def test_geometry_refuses_a_link_planted_as_its_manifest(tmp_path):
    target, out = _target(tmp_path), tmp_path / "out"
    out.mkdir()
    (out / MANIFEST_NAME).symlink_to(target)
    status, err = _run([*GEOMETRY, "--out", str(out)])
    assert status == 2, err[-2000:]
    assert MANIFEST_NAME in err and "symbolic link" in err and "Traceback" not in err
    assert target.read_text() == WORDS


def test_end_loss_refuses_a_link_planted_over_a_file_it_wrote(tmp_path):
    target, out = _target(tmp_path), tmp_path / "out"
    status, err = _run([*END_LOSS, "--out", str(out)])
    assert status == 0, err[-2000:]
    (out / "end_loss_days.csv").unlink()
    (out / "end_loss_days.csv").symlink_to(target)
    status, err = _run([*END_LOSS, "--out", str(out)])
    assert status == 2, err[-2000:]
    assert "end_loss_days.csv" in err and "Traceback" not in err
    assert target.read_text() == WORDS and (out / "end_loss_days.csv").is_symlink()


def test_export_ssp_refuses_a_link_given_as_its_file(tmp_path, fmu_paths, capsys):
    target = _target(tmp_path)
    link = tmp_path / "system.ssp"
    link.symlink_to(target)
    assert main(["export-ssp", SCENARIO, "--out", str(link)]) == 2
    err = capsys.readouterr().err
    assert str(link) in err and "symbolic link" in err
    assert target.read_text() == WORDS and link.is_symlink()


def test_geometry_keeps_a_file_an_old_manifest_lists_without_records(tmp_path):
    out, name = tmp_path / "out", "notes.txt"
    out.mkdir()
    (out / name).write_text(WORDS)
    (out / MANIFEST_NAME).write_text(json.dumps({"files": [name], "state": "complete"}))
    status, err = _run([*GEOMETRY, "--out", str(out)])
    assert status == 0, err[-2000:]
    assert f"kept {name}" in err
    assert (out / name).read_text() == WORDS


def test_size_refuses_a_link_planted_as_its_sheet_before_sizing(tmp_path, fmu_paths):
    target, out = _target(tmp_path), tmp_path / "out"
    out.mkdir()
    (out / "sizing.json").symlink_to(target)
    status, err = _run(["size", SCENARIO, "--design-gust", "30", "--candidate", "QSH4218-35-10-027", "--out", str(out)])
    assert status == 2 and "sizing.json" in err and "Traceback" not in err
    assert target.read_text() == WORDS and (out / "sizing.json").is_symlink()
    assert sorted(p.name for p in out.iterdir()) == ["sizing.json"]  # nothing sized, nothing written
