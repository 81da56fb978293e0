"""heliostep.fmu.build and heliostep.fmu.modelica: building FMUs from models/, cached, deterministic."""

import hashlib
import re
import shutil
from importlib import resources

import pytest
from fmpy import read_model_description

from heliostep.cli import main
from heliostep.errors import InputError
from heliostep.fmu.build import build_fmu, ensure_fmu, fmu_guid
from heliostep.fmu.modelica import ModelicaError
from heliostep.paths import fmus_dir, models_dir

MODELS = models_dir()


@pytest.fixture
def models_copy(tmp_path):
    """A private copy of models/ that a test may edit."""
    target = tmp_path / "models"
    shutil.copytree(MODELS, target)
    return target


def _sha256(path):
    return hashlib.sha256(path.read_bytes()).hexdigest()


def test_up_to_date_fmu_is_not_rebuilt_and_an_edit_rebuilds_it(models_copy, tmp_path):
    out = tmp_path / "fmus"
    first = build_fmu("PanelMechanicsSmallAngle", out, models_copy)
    stamp, guid = first.stat().st_mtime_ns, fmu_guid(first)
    assert build_fmu("PanelMechanicsSmallAngle", out, models_copy).stat().st_mtime_ns == stamp

    source = models_copy / "PanelMechanicsSmallAngle.mo"
    source.write_text(source.read_text().replace('J_p(unit = "kg.m2") = 3.37', 'J_p(unit = "kg.m2") = 4.2'))
    rebuilt = build_fmu("PanelMechanicsSmallAngle", out, models_copy)
    assert fmu_guid(rebuilt) != guid
    variables = {v.name: v for v in read_model_description(str(rebuilt)).modelVariables}
    assert float(variables["J_p"].start) == 4.2


def test_building_twice_gives_identical_fmus(tmp_path):
    first = build_fmu("DriveSystem", tmp_path / "a", force=True)
    second = build_fmu("DriveSystem", tmp_path / "b", force=True)
    assert _sha256(first) == _sha256(second)


def test_fmu_ships_its_sources_and_a_binary(fmu_paths):
    import zipfile

    names = zipfile.ZipFile(fmu_paths["DriveSystem"]).namelist()
    for expected in (
        "modelDescription.xml",
        "binaries/linux64/DriveSystem.so",
        "sources/fmi2_model_exchange.c",
        "sources/model_exchange_core.h",
        "sources/equations.c",
        "sources/model.h",
    ):
        assert expected in names


def _write_model(folder, name, body):
    folder.mkdir(exist_ok=True)
    (folder / f"{name}.mo").write_text(body)
    return folder


def test_syntax_error_names_file_and_line_and_leaves_no_fmu(tmp_path):
    models = _write_model(
        tmp_path / "bad", "Broken", "model Broken\n  Real x(start = 1)\nequation\n  der(x) = -x;\nend Broken;\n"
    )
    out = tmp_path / "out"
    with pytest.raises(ModelicaError) as error:
        build_fmu("Broken", out, models)
    assert f"{models / 'Broken.mo'}:3: syntax error" in str(error.value)
    assert not list(out.glob("*.fmu*"))


def test_unsupported_construct_names_file_line_and_reason(tmp_path):
    body = (
        "model Bouncing\n  Real h(start = 1);\n  Real v;\nequation\n  der(h) = v;\n  der(v) = -9.81;\n"
        "  when h < 0 then\n    reinit(v, -v);\n  end when;\nend Bouncing;\n"
    )
    models = _write_model(tmp_path / "bad", "Bouncing", body)
    with pytest.raises(ModelicaError, match=r"Bouncing\.mo:7: unsupported construct: discrete-time 'when'"):
        build_fmu("Bouncing", tmp_path / "out", models)


def test_unbalanced_model_is_refused(tmp_path):
    models = _write_model(
        tmp_path / "bad",
        "Loose",
        "model Loose\n  Real x(start = 1);\n  Real y;\nequation\n  der(x) = -x + y;\nend Loose;\n",
    )
    with pytest.raises(ModelicaError, match="Loose.mo: .*not balanced: 1 equations for 2 unknowns"):
        build_fmu("Loose", tmp_path / "out", models)


def test_unknown_model_lists_the_available_ones(tmp_path):
    with pytest.raises(InputError, match="no model 'StepMotor'; available: .*StepperMotor"):
        build_fmu("StepMotor", tmp_path)


def test_ensure_fmu_takes_paths_names_and_dropped_fmus(fmu_paths, tmp_path):
    dropped = tmp_path / "fmus"
    dropped.mkdir()
    shutil.copy(fmu_paths["StepperMotor"], dropped / "VendorMotor.fmu")
    assert ensure_fmu("VendorMotor", fmus=dropped) == dropped / "VendorMotor.fmu"
    assert ensure_fmu(fmu_paths["DriveSystem"]) == fmu_paths["DriveSystem"]
    with pytest.raises(InputError, match="unknown FMU variant 'NoSuchMotor'.*known variants: .*StepperMotor"):
        ensure_fmu("NoSuchMotor", fmus=dropped)
    with pytest.raises(InputError, match="FMU file not found"):
        ensure_fmu(tmp_path / "missing.fmu")


def test_cli_builds_named_model(tmp_path, capsys):
    assert main(["build-fmus", "--model", "StepperMotor", "--out", str(tmp_path)]) == 0
    assert (tmp_path / "StepperMotor.fmu").exists()
    assert str(tmp_path / "StepperMotor.fmu") in capsys.readouterr().out


def test_cli_reports_bad_model_with_exit_status_2(tmp_path, capsys):
    models = _write_model(tmp_path / "bad", "Broken", "model Broken\n  Real x\nend Broken;\n")
    status = main(["build-fmus", "--models", str(models), "--out", str(tmp_path / "out")])
    assert status == 2
    assert "Broken.mo:3: syntax error" in capsys.readouterr().err


def test_cli_reports_a_failed_build_as_a_run_failure_with_exit_status_1(tmp_path, capsys, monkeypatch):
    """A compiler or packaging failure is a run failure (exit 1, one line on stderr), not bad input (2)."""
    import heliostep.fmu.build as build
    from heliostep.errors import RunFailure
    from heliostep.fmu.export import BuildError

    def failing_export(*args, **kwargs):
        raise BuildError("gcc failed: no space left on device")

    monkeypatch.setattr(build, "export_fmu", failing_export)
    assert issubclass(BuildError, RunFailure) and not issubclass(BuildError, InputError)
    status = main(["build-fmus", "--model", "StepperMotor", "--out", str(tmp_path / "out"), "--force"])
    assert status == 1
    building = f"heliostep: building StepperMotor.fmu (--force, cached in {fmus_dir()})\n"  # the build said first
    assert capsys.readouterr().err == building + "heliostep build-fmus: error: gcc failed: no space left on device\n"


@pytest.mark.parametrize("layer", ["fmi2_model_exchange.c", "fmi3_model_exchange.c"])
def test_every_entry_point_of_a_layer_runs_between_begin_and_end_function(layer):
    """Each fmiXStatus entry point checks the state and its arguments in BEGIN_FUNCTION and leaves
    through END_FUNCTION (UNSUPPORTED holds both), so every error takes the one way out."""
    source = (resources.files("heliostep.fmu") / "c" / layer).read_text()
    bodies = re.findall(r"^fmi[23]Status fmi[23]\w+\(.*?\n\}", source, re.S | re.M)
    assert len(bodies) > 20
    for body in bodies:
        assert "BEGIN_FUNCTION(" in body and "END_FUNCTION()" in body or "UNSUPPORTED(" in body, body
        assert "return" not in body, body
