"""Roles, not instance names: the shipped paper case with its FMU instances renamed gives the same figures."""

from __future__ import annotations

import pytest

from heliostep.errors import InputError
from heliostep.paths import scenarios_dir
from heliostep.run import run_scenario

SCENARIO = scenarios_dir() / "jan21-central.yaml"
SHORT = ("window.duration=60",)
RENAMED = (
    "fmus.motor=null",
    "fmus.mechanics=null",
    "fmus.coil=StepperMotor",
    "fmus.panel=PanelMechanics",
    "connections=[[coil.tau, panel.tau], [panel.theta, coil.theta], [panel.omega, coil.omega]]",
    "roles={current_a_ref: coil.i_a_ref, current_b_ref: coil.i_b_ref, wind_moment: panel.m_ext, "
    "torque: coil.tau, current_a: coil.i_a, current_b: coil.i_b, power: coil.power, rotor_angle: panel.theta, "
    "panel_angle: panel.theta_p, panel_angle_start: panel.theta_p_start, rotor_angle_start: panel.theta_start, "
    "pinion_radius: panel.r, lever_arm: panel.s, current_a_start: coil.i_a_start, current_b_start: coil.i_b_start}",
)


def test_renamed_instances_give_the_same_figures():
    default = run_scenario(SCENARIO, overrides=SHORT)
    renamed = run_scenario(SCENARIO, overrides=SHORT + RENAMED)
    assert set(renamed.scenario.fmus) == {"coil", "panel"}
    assert "coil.tau" in renamed.trace and "motor.tau" not in renamed.trace
    assert default.summary["steps_commanded"] >= 3  # the window has steps to judge
    for key, value in default.summary.items():
        if key != "rows":
            assert renamed.summary[key] == value, key
    assert (
        renamed.metadata["parameters"]["panel"]["theta_p_start"]
        == default.metadata["parameters"]["mechanics"]["theta_p_start"]
    )


def test_renamed_instances_without_roles_name_the_missing_roles():
    with pytest.raises(
        InputError, match=r"roles\.current_a_ref: the default 'motor\.i_a_ref' uses FMU instance 'motor'"
    ):
        run_scenario(SCENARIO, overrides=SHORT + RENAMED[:-1])


def test_a_role_naming_a_missing_variable_is_an_input_error():
    with pytest.raises(InputError, match=r"roles\.torque: .*has no variable 'torque'"):
        run_scenario(SCENARIO, overrides=SHORT + ("roles.torque=motor.torque",))
    with pytest.raises(InputError, match=r"roles\.torque: motor\.i_a_ref has causality 'input', expected 'output'"):
        run_scenario(SCENARIO, overrides=SHORT + ("roles.torque=motor.i_a_ref",))


@pytest.fixture(scope="module")
def vendor_scenario(tmp_path_factory):
    """A vendor motor FMU (the shipped motor with its inputs and torque renamed: iaRef, ibRef, tauEl, built
    by heliostep's own chain into an fmus/ folder beside a copy of the paper's scenario), as a user drops one."""
    import re
    import shutil

    from heliostep.fmu.build import build_fmu
    from heliostep.paths import models_dir

    tmp_path = tmp_path_factory.mktemp("vendor")
    models = tmp_path / "models"
    models.mkdir()
    source = (models_dir() / "StepperMotor.mo").read_text()
    renamed = re.sub(r"\bStepperMotor\b", "VendorMotor", source)
    renamed = re.sub(r"\bi_a_ref\b", "iaRef", re.sub(r"\bi_b_ref\b", "ibRef", re.sub(r"\btau\b", "tauEl", renamed)))
    (models / "VendorMotor.mo").write_text(renamed)
    (tmp_path / "fmus").mkdir()
    built = build_fmu("VendorMotor", tmp_path / "cache", models)  # into a cache of its own, keyed by build
    shutil.copy(built, tmp_path / "fmus" / "VendorMotor.fmu")  # dropped beside the scenario, as a user does
    scenario = tmp_path / "vendor.yaml"
    shutil.copy(SCENARIO, scenario)
    return scenario


def test_a_vendor_motor_with_other_names_and_only_fmus_set_names_the_roles_to_spell_out(vendor_scenario):
    # issue #24: a vendor motor FMU and only fmus.motor set: an input error naming each required role, the
    # default variable it looked for and the FMU's inputs, not a KeyError
    with pytest.raises(InputError) as error:
        run_scenario(vendor_scenario, overrides=SHORT + ("fmus.motor=VendorMotor",))
    message = str(error.value)
    assert "roles.current_a_ref: the default 'motor.i_a_ref' names no variable of VendorMotor.fmu" in message
    assert "roles.current_b_ref" in message and "its inputs: iaRef, ibRef" in message and "connections" in message


def test_a_vendor_motor_is_refused_with_its_variables_and_a_block_that_fits_which_runs(vendor_scenario):
    # issue #24: the refusal lists the FMUs' inputs and outputs with units and proposes the connections and
    # roles matched by causality, unit and name; that block pasted into the scenario runs, and gives the
    # shipped motor's figures (the vendor motor is the shipped one renamed)
    import yaml

    with pytest.raises(InputError) as error:
        run_scenario(vendor_scenario, overrides=SHORT + ("fmus.motor=VendorMotor",))
    message = str(error.value)
    assert "connections[0] source 'motor.tau': VendorMotor.fmu (instance 'motor') has no variable 'tau'" in message
    assert (
        "motor (VendorMotor.fmu): inputs iaRef [A], ibRef [A], theta [rad], omega [rad/s]; outputs i_a [A]" in message
    )
    assert (
        "tauEl [N.m], v_a [V]" in message and "mechanics (PanelMechanics.fmu): inputs tau [N.m], m_ext [N.m]" in message
    )
    block = message.split("would fit", 1)[1].split(":\n", 1)[1]
    proposal = yaml.safe_load(block)
    assert proposal["connections"] == [
        ["motor.tauEl", "mechanics.tau"],
        ["mechanics.theta", "motor.theta"],
        ["mechanics.omega", "motor.omega"],
    ]
    assert proposal["roles"]["current_a_ref"] == "motor.iaRef" and proposal["roles"]["current_b_ref"] == "motor.ibRef"
    assert proposal["roles"]["torque"] == "motor.tauEl" and proposal["roles"]["rotor_angle"] == "mechanics.theta"
    assert proposal["roles"]["current_a"] == "motor.i_a" and proposal["roles"]["wind_moment"] == "mechanics.m_ext"
    pasted = vendor_scenario.with_name("vendor-fitted.yaml")
    text = vendor_scenario.read_text().replace("motor: StepperMotor,", "motor: VendorMotor,")
    pasted.write_text(text + "\n" + block + "\n")
    fitted = run_scenario(pasted, overrides=SHORT)
    default = run_scenario(SCENARIO, overrides=SHORT)
    assert "motor.tauEl" in fitted.trace and default.summary["steps_commanded"] >= 3
    for key, value in default.summary.items():
        if key != "rows":
            assert fitted.summary[key] == value, key


def test_the_command_line_refuses_a_vendor_motor_with_exit_2_and_the_block(vendor_scenario, tmp_path, capsys):
    from heliostep.cli import main

    out = tmp_path / "out"
    args = [
        "run",
        str(vendor_scenario),
        "--out",
        str(out),
        "--set",
        "window.duration=20",
        "--set",
        "fmus.motor=VendorMotor",
    ]
    assert main(args) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err and "heliostep run: error:" in err
    assert "\nconnections:\n  - [motor.tauEl, mechanics.tau]\n" in err and "\n  torque: motor.tauEl\n" in err
    # the last line, which logs and CI show, names the file and the exit status too
    assert err.strip().splitlines()[-1].startswith(f"heliostep run: error (exit 2) above: {vendor_scenario}: ")
    assert not out.exists()  # refused before anything was written
