"""The drive's energy over 24 h with the night's policy (``sequencer.night``): the figure of a five-minute
window against a co-simulated day and night, and the night's power against R i^2 by hand."""

from __future__ import annotations

import pytest

from heliostep.errors import InputError
from heliostep.paths import scenarios_dir
from heliostep.run import run_scenario
from physics_reference import HELD_CURRENT, TABLE3_MOTOR


def _summary(*overrides):
    return run_scenario(scenarios_dir() / "jan21-central.yaml", overrides=overrides).summary


def test_a_held_drives_24h_energy_is_what_a_day_and_a_night_co_simulated_draw(fmu_paths):
    # the paper's drive holds its full current between steps and through the night (idle fraction 1): the
    # figure of its five minutes equals the electrical energy of 24 h co-simulated step by step (1 941 steps)
    window = _summary()
    day = _summary("window.duration=86400", "output.interval=60", "output.step_detail=0")
    assert day["steps_commanded"] > 1900
    assert window["drive_energy_24h_J"] == pytest.approx(day["electrical_energy_J"], rel=1e-4)
    assert window["drive_energy_24h_J"] > 2 * window["drive_energy_per_day_J"]  # the long January night


@pytest.mark.parametrize(
    "overrides, phases, fraction",
    [
        ((), 1, 1.0),  # idle at the idle fraction, 1 here: the full current
        (("sequencer.night=hold", "sequencer.idle_current_fraction=0.3"), 1, 1.0),
        (("sequencer.night=idle", "sequencer.idle_current_fraction=0.3"), 1, 0.3),
        (("sequencer.night=off",), 1, 0.0),  # a self-locking drive needs no current
        (("sequencer.mode=two-phase-on", "sequencer.night=hold"), 2, 1.0),
    ],
)
def test_the_nights_power_is_r_i_squared_of_the_phases_held(fmu_paths, overrides, phases, fraction):
    summary = _summary("window.duration=30", *overrides)
    expected = phases * TABLE3_MOTOR["R"] * (fraction * HELD_CURRENT) ** 2  # R i^2 per phase on, i = K f I / (K + R)
    assert summary["night_power_W"] == pytest.approx(expected, rel=1e-12, abs=1e-15)
    daylight = summary["drive_energy_per_day_J"] / summary["drive_power_mean_W"]
    night = summary["drive_energy_24h_J"] - summary["drive_energy_per_day_J"]
    assert night == pytest.approx(expected * (86400.0 - daylight), rel=1e-9, abs=1e-9)


def test_an_unknown_night_policy_is_refused_naming_the_key():
    with pytest.raises(InputError, match=r"sequencer\.night.*'hold', 'idle' or 'off'"):
        _summary("sequencer.night=dark")
