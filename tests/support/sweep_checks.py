"""What the sweep tests share: the figures a case's row and its run's summary both hold, and the check that a
bad sweep is refused before any of its cases runs."""

from __future__ import annotations

from pathlib import Path

import pytest

from heliostep.errors import InputError
from heliostep.sweep import run_sweep

#: Figures a case's row and its run's summary hold under the same name, plain numbers.
PLAIN_FIGURES = (
    "max_tracking_error_deg",
    "rms_tracking_error_deg",
    "peak_torque_Nm",
    "peak_phase_current_A",
    "electrical_energy_J",
    "steps_commanded",
    "steps_executed",
    "missed_steps",
    "duration_s",
    "light_energy_J",
    "light_energy_ideal_J",
    "light_lost_J",
    "light_lost_stepping_J",
    "light_lost_shared_primary_J",
    "mean_intercept",
    "drive_energy_per_day_J",
)


def assert_refused_before_any_case(sweep: Path, results: Path, client, words) -> None:
    """``run_sweep(sweep)`` raises InputError naming ``sweep`` and each of ``words``; no case ran, no table made."""
    ran = []
    with pytest.raises(InputError) as error:
        run_sweep(sweep, results, client=client, on_result=ran.append)
    message = str(error.value)
    assert str(sweep) in message
    for word in words:
        assert word in message
    assert not ran and not results.exists()
