"""A model variant in ``models/`` beside the user's scenario is found (before the shipped models and
``$HELIOSTEP_MODELS``), built and run; a variant found nowhere is exit 2 naming each path looked at once and
``heliostep build-fmus`` (docs/running.md, "Where a variant is looked for"). Real builds and runs."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from fmpy import read_model_description

from heliostep.cli import main
from heliostep.fmu.build import variant_folders
from heliostep.paths import fmus_dir, models_dir, scenarios_dir

SHORT = ["--no-plots", "--set", "window.duration=20"]


def _scenario_with_models(folder: Path, models: dict[str, str], motor: str) -> Path:
    """jan21-central copied into ``folder`` with ``fmus.motor: motor`` and ``models/NAME.mo`` beside it."""
    (folder / "models").mkdir(parents=True)
    for name, text in models.items():
        (folder / "models" / f"{name}.mo").write_text(text)
    text = (scenarios_dir() / "jan21-central.yaml").read_text()
    path = folder / "mine.yaml"
    path.write_text(text.replace("fmus: {motor: StepperMotor,", f"fmus: {{motor: {motor},"))
    assert f"motor: {motor}," in path.read_text()
    return path


def _shipped_motor() -> str:
    return (models_dir() / "StepperMotor.mo").read_text()


def test_a_variant_in_models_beside_the_scenario_runs_from_another_folder(tmp_path, monkeypatch, capsys):
    mine = _shipped_motor().replace("StepperMotor", "MyMotor")
    scenario = _scenario_with_models(tmp_path / "site", {"MyMotor": mine}, "MyMotor")
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)
    assert main(["run", str(scenario), *SHORT, "--out", "mine"]) == 0, capsys.readouterr().err
    assert main(["run", "jan21-central", *SHORT, "--out", "shipped"]) == 0, capsys.readouterr().err
    mine_meta = json.loads((elsewhere / "mine" / "metadata.json").read_text())
    shipped_meta = json.loads((elsewhere / "shipped" / "metadata.json").read_text())
    assert Path(mine_meta["fmus"]["motor"]["path"]).name == "MyMotor.fmu"
    assert mine_meta["fmus"]["motor"]["sha256"] != shipped_meta["fmus"]["motor"]["sha256"]
    # the same equations under another name: the same figures
    mine_summary = json.loads((elsewhere / "mine" / "summary.json").read_text())
    shipped_summary = json.loads((elsewhere / "shipped" / "summary.json").read_text())
    for key in ("steps_commanded", "missed_steps", "steps_lost", "max_tracking_error_deg", "peak_torque_Nm"):
        assert mine_summary[key] == pytest.approx(shipped_summary[key], rel=1e-9, abs=1e-12), key


def test_the_scenarios_models_come_before_the_shipped_ones_of_the_same_name(tmp_path, monkeypatch, capsys):
    default = 'parameter Real R(unit = "Ohm") = 0.1 '
    assert default in _shipped_motor()
    mine = _shipped_motor().replace(default, 'parameter Real R(unit = "Ohm") = 0.4 ')
    scenario = _scenario_with_models(tmp_path / "site", {"StepperMotor": mine}, "StepperMotor")
    monkeypatch.chdir(tmp_path)
    assert main(["run", str(scenario), *SHORT, "--out", "out"]) == 0, capsys.readouterr().err
    metadata = json.loads((tmp_path / "out" / "metadata.json").read_text())
    description = read_model_description(metadata["fmus"]["motor"]["path"])
    assert next(v.start for v in description.modelVariables if v.name == "R") == "0.4"


def test_the_order_of_the_folders_each_once(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("HELIOSTEP_MODELS", str(tmp_path / "env-models"))
    model_folders, fmu_folders = variant_folders(tmp_path)
    assert model_folders == [tmp_path / "models", tmp_path / "env-models"]
    assert fmu_folders == [tmp_path / "fmus", fmus_dir()]  # the scenario's folder is the current one: once
    assert variant_folders(tmp_path / "site")[1] == [tmp_path / "site" / "fmus", tmp_path / "fmus", fmus_dir()]


def test_an_unknown_variant_names_each_path_once_and_build_fmus(tmp_path, monkeypatch, capsys):
    scenario = _scenario_with_models(tmp_path, {}, "MyMotr")
    monkeypatch.chdir(tmp_path)
    assert main(["run", scenario.name, *SHORT, "--out", "out"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("heliostep run: error: mine.yaml: fmus.motor: unknown FMU variant 'MyMotr': none of ")
    looked = [
        tmp_path / "models" / "MyMotr.mo",
        models_dir() / "MyMotr.mo",
        tmp_path / "fmus" / "MyMotr.fmu",
        fmus_dir() / "MyMotr.fmu",
    ]
    listed = err.partition("none of ")[2].partition(" exists")[0].split(", ")
    assert listed == [str(path) for path in looked]
    assert "StepperMotor" in err.partition("known variants: ")[2]
    assert "`heliostep build-fmus --models DIR --model NAME`" in err
    assert not (tmp_path / "out").exists()
