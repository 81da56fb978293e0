"""heliostep installed like a library (``pip install .``, not editable) runs a shipped scenario
from another directory: models and scenarios are package data, built FMUs go to the user cache."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

PROJECT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def installed(tmp_path_factory) -> Path:
    """heliostep installed non-editable into a folder of its own (its dependencies: this venv's).

    Built from a copy of the checkout: setuptools builds in the source tree (``build/``), where the
    suite's two workers, each with this module's fixture, would collide, and the checkout is not the
    test's to write in.
    """
    target = tmp_path_factory.mktemp("site")
    source = tmp_path_factory.mktemp("checkout")
    for name in ("pyproject.toml", "README.md", "LICENSE"):
        shutil.copy2(PROJECT / name, source / name)
    skip = shutil.ignore_patterns("__pycache__", "*.egg-info")
    for name in ("src", "models", "scenarios"):
        shutil.copytree(PROJECT / name, source / name, ignore=skip)
    result = subprocess.run(
        [
            sys.executable,
            "-m",
            "pip",
            "install",
            "--quiet",
            "--no-deps",
            "--no-build-isolation",
            "--no-index",
            "--target",
            str(target),
            str(source),
        ],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert result.returncode == 0, result.stderr[-3000:]
    return target


def _run(installed: Path, cwd: Path, *args: str, env: dict | None = None) -> subprocess.CompletedProcess:
    environment = {k: v for k, v in os.environ.items() if k not in ("HELIOSTEP_MODELS", "PYTHONPATH")}
    environment.update(PYTHONPATH=str(installed), **(env or {}))
    code = "from heliostep.cli import console_main; console_main()"
    return subprocess.run(
        [sys.executable, "-c", code, *args], cwd=cwd, env=environment, capture_output=True, text=True, timeout=300
    )


def test_installed_package_carries_models_and_scenarios(installed):
    data = installed / "heliostep" / "data"
    assert {p.name for p in (data / "models").glob("*.mo")} >= {"StepperMotor.mo", "PanelMechanics.mo"}
    assert (data / "scenarios" / "jan21-central.yaml").is_file()
    assert (data / "scenarios" / "jan21-central.reference.parquet").is_file()
    assert (data / "motors.yaml").is_file()  # heliostep size's motor catalogue (issue 23)
    assert (installed / "heliostep" / "fmu" / "c" / "fmi2_model_exchange.c").is_file()
    # the installed command is console_main: main, its status the exit status (tests/cli/test_installed_command.py)
    (entry_points,) = installed.glob("heliostep-*.dist-info/entry_points.txt")
    assert "heliostep = heliostep.cli:console_main" in entry_points.read_text().splitlines()


def test_shipped_scenario_runs_from_another_directory(installed, tmp_path, fmu_paths):
    where = _run(installed, tmp_path, "--version")
    assert where.returncode == 0
    probe = subprocess.run(
        [
            sys.executable,
            "-c",
            "import heliostep, heliostep.paths as p; "
            "print(heliostep.__file__); print(p.models_dir()); print(p.scenarios_dir())",
        ],
        cwd=tmp_path,
        env={**os.environ, "PYTHONPATH": str(installed)},
        capture_output=True,
        text=True,
        timeout=60,
    )
    module, models, scenarios = probe.stdout.split()
    assert Path(module).is_relative_to(installed)  # the installed copy, not the checkout
    assert Path(models).is_relative_to(installed) and Path(scenarios).is_relative_to(installed)
    fmus = tmp_path / "cache"
    result = _run(
        installed,
        tmp_path,
        "run",
        "jan21-central",
        "--set",
        "window.duration=3",
        "--no-plots",
        "--out",
        "result",
        env={"HELIOSTEP_FMUS": str(fmus)},
    )
    assert result.returncode == 0, result.stderr[-3000:]
    summary = json.loads((tmp_path / "result" / "summary.json").read_text())
    assert summary["complete"] is True and summary["duration_s"] == pytest.approx(3.0)
    assert {p.name for p in fmus.glob("*/*.fmu")} == {"StepperMotor.fmu", "PanelMechanics.fmu"}  # CACHE/KEY16/NAME.fmu


def test_users_own_fmus_folder_beside_the_scenario(installed, tmp_path, fmu_paths):
    # a vendor FMU dropped into fmus/ beside the user's scenario is found by its name
    (tmp_path / "fmus").mkdir()
    (tmp_path / "fmus" / "VendorMotor.fmu").write_bytes(fmu_paths["StepperMotor"].read_bytes())
    scenario = (PROJECT / "scenarios" / "jan21-central.yaml").read_text()
    (tmp_path / "mine.yaml").write_text(scenario)
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    result = _run(
        installed,
        elsewhere,
        "run",
        str(tmp_path / "mine.yaml"),
        "--set",
        "fmus.motor=VendorMotor",
        "--set",
        "window.duration=2",
        "--no-plots",
        "--out",
        "out",
    )
    assert result.returncode == 0, result.stderr[-3000:]
    metadata = json.loads((elsewhere / "out" / "metadata.json").read_text())
    assert metadata["fmus"]["motor"]["path"] == str(tmp_path / "fmus" / "VendorMotor.fmu")


def test_installed_package_carries_the_parameter_ranges(installed, tmp_path):
    """``--band``'s ranges file is package data: an installed heliostep finds and reads it."""
    assert (installed / "heliostep" / "data" / "parameter_ranges.yaml").is_file()
    environment = {k: v for k, v in os.environ.items() if k not in ("HELIOSTEP_MODELS", "PYTHONPATH")}
    code = (
        "from heliostep.sweep.band import RANGES_FILE, load_ranges; "
        "print(RANGES_FILE); print(sorted(p.key for p in load_ranges()))"
    )
    done = subprocess.run(
        [sys.executable, "-c", code],
        cwd=tmp_path,
        env={**environment, "PYTHONPATH": str(installed)},
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 0, done.stderr
    path, keys = done.stdout.splitlines()
    assert Path(path).resolve() == (installed / "heliostep" / "data" / "parameter_ranges.yaml").resolve()
    assert keys == "['parameters.mechanics.B_m', 'parameters.motor.K_current', 'parameters.motor.V_supply']"
