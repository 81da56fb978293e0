"""Shared fixtures: the project's FMUs, built from models/ on first use (cached by content)."""

import signal

import pytest

from heliostep.fmu.build import build_fmu
from shipped_models import MODELS

pytest.register_assert_rewrite("lag_reference")  # its checks say their values when they fail, as a test's do


def pytest_configure(config):
    """A suite started in the background (a shell's ``&``, ``nohup``) inherits SIGINT and SIGHUP ignored, and
    so would every process the tests start (an ignored signal stays ignored across exec): the signal tests
    need the defaults, which a terminal's run has."""
    for sig, default in ((signal.SIGINT, signal.default_int_handler), (signal.SIGHUP, signal.SIG_DFL)):
        if signal.getsignal(sig) is signal.SIG_IGN:
            signal.signal(sig, default)


@pytest.fixture(scope="session")
def fmu_paths():
    """name -> path of every shipped model's FMU (built into fmus/ when missing or stale)."""
    return {name: build_fmu(name) for name in MODELS}
