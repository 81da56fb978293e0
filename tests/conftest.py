"""Shared fixtures: the project's FMUs, built from models/ on first use (cached by content)."""

import pytest

from heliostep.fmu.build import build_fmu

MODELS = ("StepperMotor", "StepperMotorIdealCurrent", "PanelMechanics", "PanelMechanicsSmallAngle", "DriveSystem")


@pytest.fixture(scope="session")
def fmu_paths():
    """name -> path of every shipped model's FMU (built into fmus/ when missing or stale)."""
    return {name: build_fmu(name) for name in MODELS}
