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
    default = run_scenario(SCENARIO, SHORT)
    renamed = run_scenario(SCENARIO, SHORT + RENAMED)
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
        run_scenario(SCENARIO, SHORT + RENAMED[:-1])


def test_a_role_naming_a_missing_variable_is_an_input_error():
    with pytest.raises(InputError, match=r"roles\.torque: .*has no variable 'torque'"):
        run_scenario(SCENARIO, SHORT + ("roles.torque=motor.torque",))
    with pytest.raises(InputError, match=r"roles\.torque: motor\.i_a_ref has causality 'input', expected 'output'"):
        run_scenario(SCENARIO, SHORT + ("roles.torque=motor.i_a_ref",))


def test_a_vendor_motor_with_other_names_and_only_fmus_set_names_the_roles_to_spell_out(tmp_path):
    # issue #24: a vendor motor FMU (here the shipped motor with its inputs and torque renamed, built by
    # heliostep's own chain into an fmus/ folder beside the scenario) and only fmus.motor set: an input error
    # naming each required role, the default variable it looked for and the FMU's inputs, not a KeyError
    import re
    import shutil

    from heliostep.fmu.build import build_fmu
    from heliostep.paths import models_dir

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
    with pytest.raises(InputError) as error:
        run_scenario(scenario, SHORT + ("fmus.motor=VendorMotor",))
    message = str(error.value)
    assert "roles.current_a_ref: the default 'motor.i_a_ref' names no variable of VendorMotor.fmu" in message
    assert "roles.current_b_ref" in message and "its inputs: iaRef, ibRef" in message and "connections" in message
