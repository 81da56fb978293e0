"""Fixtures of the master's tests."""

import pytest

from heliostep.cosim.fmi import read_fmu


@pytest.fixture(scope="module")
def drive(fmu_paths):
    """The shipped motor and mechanics FMUs, read (instances ``motor`` and ``mechanics``)."""
    return {"motor": read_fmu(fmu_paths["StepperMotor"]), "mechanics": read_fmu(fmu_paths["PanelMechanics"])}
