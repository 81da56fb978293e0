"""``heliostep motors`` and ``heliostep run --motor`` (issue 57): the catalogue listed, a catalogue motor run
by name, its parameters those of its datasheet (k_e = T_hold / (sqrt(2) I_rated), docs/physics.md)."""

from __future__ import annotations

import json
import math

import pytest

from heliostep.paths import scenarios_dir
from heliostep.scenario.catalogue import load_catalogue
from heliostep_process import popen_heliostep

SCENARIO = str(scenarios_dir() / "jan21-central.yaml")


def _heliostep(args: list[str]) -> tuple[int, str, str]:
    process = popen_heliostep(args)
    out, err = process.communicate(timeout=300)
    return process.returncode, out, err


def test_motors_lists_every_entry_with_its_source():
    status, out, err = _heliostep(["motors"])
    assert status == 0, err
    for candidate in load_catalogue():
        line = next(line for line in out.splitlines() if line.startswith(candidate.name + " "))
        assert candidate.datasheet in line and candidate.manufacturer in line


def test_motors_with_a_bad_catalogue_is_exit_2_naming_file_and_key(tmp_path):
    path = tmp_path / "mine.yaml"
    path.write_text("motors:\n  m1:\n    manufacturer: X\n")
    status, _, err = _heliostep(["motors", "--catalogue", str(path)])
    assert status == 2 and str(path) in err and "motors.m1.model: missing" in err


def test_run_with_an_unknown_motor_is_exit_2_naming_it(tmp_path):
    status, _, err = _heliostep(["run", SCENARIO, "--motor", "NEMA99-X", "--no-plots", "--out", str(tmp_path / "o")])
    assert status == 2 and "'NEMA99-X'" in err and "motors.yaml" in err
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize("name", ["QSH5718-76-28-189"])
def test_run_with_a_catalogue_motor_sets_its_datasheet_values(tmp_path, name):
    out = tmp_path / "o"
    args = ["run", SCENARIO, "--motor", name, "--current", "2.1", "--set", "window.duration=2", "--no-plots"]
    status, _, err = _heliostep([*args, "--out", str(out)])
    assert status == 0, err
    metadata = json.loads((out / "metadata.json").read_text())
    assert metadata["motor"]["name"] == name and metadata["motor"]["current_A"] == 2.1
    # QMot QSH5718 manual V2.6, Table 2.1: 1.89 N.m at 2.8 A, 1.13 Ohm, 3.6 mH, 480 g.cm2, 0.066 N.m, 1.8 deg;
    # the test's bus: its torque figures' 30 V
    motor, mechanics = metadata["parameters"]["motor"], metadata["parameters"]["mechanics"]
    assert motor["k_e"] == pytest.approx(1.89 / (math.sqrt(2.0) * 2.8))
    assert (motor["R"], motor["L"], motor["T_d"], motor["V_supply"]) == pytest.approx((1.13, 3.6e-3, 0.066, 30.0))
    assert motor["N_c"] == pytest.approx(90.0 / 1.8)
    assert mechanics["J_m"] == pytest.approx(480e-7)
    sequencer = metadata["scenario"]["sequencer"]
    assert sequencer["current"] == 2.1 and sequencer["step_angle"] == 1.8
    assert json.loads((out / "summary.json").read_text())["complete"] is True
