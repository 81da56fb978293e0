"""A sizing sheet its ``--out`` cannot take loses no finished case: ``sizing.json`` goes into a rescue folder,
one line names the folder that failed and the rescue, exit 1, no traceback.

The failure is real: ``--out`` is moved away once the cases have finished (a folder deleted under a running
command), so the sheet's staging folder cannot be made there. The cases run for real (one candidate, one
day, a 20 s window)."""

from __future__ import annotations

import json
import tempfile

import yaml

import heliostep.sizing.sheet as sheet_module
from catalogue_entries import QSH8618_65_AT_3A
from heliostep.cli import main
from heliostep.paths import scenarios_dir

SCENARIO = str(scenarios_dir() / "jan21-central.yaml")
ENTRY = QSH8618_65_AT_3A


def test_a_sheet_the_folder_cannot_take_is_rescued_with_every_finished_case(tmp_path, capsys, monkeypatch, fmu_paths):
    catalogue = tmp_path / "motors.yaml"
    catalogue.write_text(yaml.safe_dump({"motors": {"small": ENTRY}}), encoding="utf-8")
    out, gone = tmp_path / "out", tmp_path / "out-moved-away"
    rescues = tmp_path / "tmp"
    rescues.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(rescues))  # where the rescue folder is made
    run_cases = sheet_module.run_sizing_cases

    def cases_then_folder_gone(plan, **options):
        results = run_cases(plan, **options)  # the real cases, then --out moved away before the sheet
        out.rename(gone)
        return results

    monkeypatch.setattr(sheet_module, "run_sizing_cases", cases_then_folder_gone)
    argv = ["size", SCENARIO, "--catalogue", str(catalogue), "--days", "21", "--curve-rates", "5"]
    argv += ["--design-gust", "60", "--set", "window.duration=20", "--no-band-days", "--out", str(out)]
    assert main(argv) == 1  # a failure, not bad input
    err = capsys.readouterr().err
    assert "Traceback" not in err and len(err.strip().splitlines()) == 1
    assert f"heliostep size: error: could not write the sizing sheet to {out} (" in err
    assert "No such file or directory" in err
    (rescue,) = rescues.glob("heliostep-jan21-central-sizing-rescue-*")
    assert f"sizing.json was written to {rescue} instead" in err
    sheet = json.loads((rescue / "sizing.json").read_text(encoding="utf-8"))
    assert sheet["complete"] is True and sheet["finished_cases"] == ["small@3A/day21"]
    day = sheet["candidates"][0]["currents"][0]["simulation"]["per_day"]["21"]
    assert day["steps_commanded"] > 0 and day["electrical_energy_J"] > 0  # the case's figures kept
    assert not out.exists()  # nothing was made anew where --out was
    assert [p.name for p in gone.iterdir() if p.name.startswith(".heliostep-tmp")] == []
