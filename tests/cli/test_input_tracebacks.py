"""Command-line input that used to end in a traceback (issue 22, items 11 and 13): each is one
line naming the option or key and what is allowed, exit 2 — or, for a run that commands no step,
a warning."""

from __future__ import annotations

import shutil
import subprocess
import sys

import pytest

from heliostep.cli import main
from heliostep.paths import scenarios_dir
from heliostep_process import HELIOSTEP

CENTRAL = scenarios_dir() / "jan21-central.yaml"


def _one_line_error(capsys) -> str:
    err = capsys.readouterr().err
    assert "Traceback" not in err and len(err.strip().splitlines()) == 1, err
    return err


@pytest.mark.parametrize(
    "args, expected",
    [
        (["end-loss", "--year", "0"], "--year 0: expected a year from 1678 to 2261"),
        (["end-loss", "--year", "99999"], "--year 99999: expected a year from 1678 to 2261"),
        (["end-loss", "--year", "1880"], "--year 1880: 1880-01-01: Europe/Rome then kept local mean time"),
        (["geometry", "--step", "1e-6"], "--step 1e-06 s: the day tables would have an estimated 3.46e+11 rows"),
        (["geometry", "--paper-case", "--window-step", "1e-7"], "--window-step 1e-07 s: the paper's window"),
        (["geometry", "--altitude", "50000"], "altitude must be within [-500, 9000] m, got 50000"),
        (["geometry", "--altitude=-1e6"], "altitude must be within [-500, 9000] m, got -1e+06"),
        (["geometry", "--date", "1600-01-01"], "--date 1600-01-01: expected a date in the years 1678 to 2261"),
        (["regress", "missing.yaml"], "missing.yaml: scenario file not found"),
    ],
)
def test_bad_command_line_input_is_one_line_and_exit_2(args, expected, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main([*args, "--out", str(tmp_path / "out")] if args[0] != "regress" else args) == 2
    assert expected in _one_line_error(capsys)
    assert not (tmp_path / "out").exists()  # refused before anything was written


def test_a_sweep_finds_a_vendor_fmu_beside_its_base_scenario_as_run_does(tmp_path, capsys, fmu_paths):
    """``motor: VendorMotor`` names ``fmus/VendorMotor.fmu`` beside the base scenario (here the
    shipped motor under another name): ``run`` found it, a sweep called it unknown."""
    (tmp_path / "fmus").mkdir()
    shutil.copy(fmu_paths["StepperMotor"], tmp_path / "fmus" / "VendorMotor.fmu")
    text = CENTRAL.read_text().replace("name: jan21-central", "name: vendor")
    text = text.replace("motor: StepperMotor,", "motor: VendorMotor,")
    assert "motor: VendorMotor," in text
    (tmp_path / "base.yaml").write_text(text)
    (tmp_path / "sweep.yaml").write_text(
        "name: vendor-sweep\nbase: base.yaml\naxes:\n  sequencer.current: [4.0, 5.5]\n"
        "overrides:\n  window.duration: 20\n"
    )
    assert main(["run", str(tmp_path / "base.yaml"), "--out", str(tmp_path / "run"), "--no-plots"]) == 0
    sweep = subprocess.run(  # a process of its own: the sweep's local Dask cluster
        [*HELIOSTEP, "sweep", str(tmp_path / "sweep.yaml"), "--out", str(tmp_path / "sweep"), "--workers", "1"],
        capture_output=True,
        text=True,
        timeout=300,
        cwd=tmp_path.parent,  # not beside fmus/: found from the base scenario's folder
    )
    assert sweep.returncode == 0 and "unknown FMU variant" not in sweep.stderr, sweep.stderr
    import pandas as pd

    table = pd.read_parquet(next((tmp_path / "sweep").glob("*.parquet")))
    assert sorted(table["sequencer.current"]) == [4.0, 5.5]
    # the holding torque k_e I of the paper's motor (k_e = 0.5 N.m/A, Table 3): the vendor FMU ran
    assert sorted(table["holding_torque_Nm"]) == pytest.approx([2.0, 2.75])


def test_a_run_that_commands_no_step_warns(tmp_path, capsys, fmu_paths):
    """A pinion of 10 m instead of 2.5 mm: the rotor turns 4000 times less for the same panel
    motion, so the paper's five minutes (16 steps of 1.8 deg with the shipped pinion) ask for
    16 x 1.8 / 4000 = 0.007 deg, under half a step; the run completes and says it stepped nothing."""
    out = tmp_path / "out"
    assert main(["run", str(CENTRAL), "--out", str(out), "--no-plots", "--set", "transmission.pinion_radius=10"]) == 0
    err = capsys.readouterr().err
    assert "warning: no step was commanded" in err and "transmission.pinion_radius" in err


@pytest.mark.parametrize(
    "axes, expected",
    [
        (
            "  sequencer.current: {start: 1, stop: 1000}\n  wind.moment: {start: 0, stop: 999}\n",
            "sequencer.current (1000 values) x wind.moment (1000 values) make 1,000,000 cases, over max_cases = 10,000",
        ),
        ("  sequencer.current: {start: 1, stop: 2, step: 1e-12}\n", "a range of 1e+12 values; expected at most"),
    ],
)
def test_a_sweep_too_large_is_refused_before_its_cases_are_built(axes, expected, tmp_path, capsys):
    sweep = tmp_path / "sweep.yaml"
    sweep.write_text(f"name: big\nbase: {CENTRAL}\naxes:\n{axes}")
    assert main(["sweep", str(sweep), "--out", str(tmp_path / "out")]) == 2
    assert expected in _one_line_error(capsys)
    assert not (tmp_path / "out").exists()
    # max_cases in the sweep file raises the bound (here: above the count, so the cases are built)
    from heliostep.sweep.axes import count_cases
    from heliostep.sweep.spec import load_sweep

    if "max_cases" in expected:
        sweep.write_text(f"name: big\nbase: {CENTRAL}\nmax_cases: 2000000\naxes:\n{axes}")
        spec = load_sweep(sweep)
        assert spec.max_cases == 2_000_000 and count_cases(spec.axes, spec.combine, spec.shared_primary) == 1000 * 1000


def test_an_integer_of_more_digits_than_python_converts_names_the_key(tmp_path, capsys):
    digits = "1" * 5000
    assert main(["run", str(CENTRAL), "--out", str(tmp_path / "out"), "--set", f"site.latitude={digits}"]) == 2
    error = _one_line_error(capsys)
    assert "an integer of 5000 digits; expected at most 4300" in error
    assert "site.latitude=" in error and "(5,016 characters)" in error and len(error) < 400  # not echoed whole
    scenario = tmp_path / "s.yaml"
    scenario.write_text(CENTRAL.read_text().replace("latitude: 40.0", f"latitude: {digits}", 1))
    assert main(["run", str(scenario), "--out", str(tmp_path / "out")]) == 2
    assert "s.yaml: not valid YAML: line" in _one_line_error(capsys)
    assert not (tmp_path / "out").exists()


def test_an_out_name_longer_than_the_file_system_takes_is_exit_2(tmp_path, capsys):
    out = tmp_path / ("x" * 300)
    assert main(["run", str(CENTRAL), "--out", str(out), "--no-plots"]) == 2
    assert "a name of 300 bytes; expected at most 255 per folder" in _one_line_error(capsys)


def test_a_deleted_current_folder_is_exit_2_naming_it(tmp_path):
    gone = tmp_path / "gone"
    gone.mkdir()
    script = (
        "import os, sys; os.chdir(sys.argv[1]); os.rmdir(sys.argv[1]); sys.argv[1:] = sys.argv[2:]; "
        "from heliostep.cli import console_main; console_main()"
    )
    completed = subprocess.run(
        [sys.executable, "-c", script, str(gone), "run", str(CENTRAL), "--out", str(tmp_path / "out"), "--no-plots"],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert completed.returncode == 2 and "Traceback" not in completed.stderr, completed.stderr
    assert "the current folder no longer exists" in completed.stderr
