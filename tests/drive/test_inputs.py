"""heliostep.drive.inputs: the reference from the sun, the step instants and the output grid."""

import numpy as np
import pandas as pd
import pytest

from heliostep.drive.inputs import output_grid, prepare_inputs
from heliostep.errors import InputError
from heliostep.run.bindings import signals as _signals
from heliostep.scenario import RolesConfig, validate_scenario
from heliostep.solar import panel_angle_reference, rotor_angle_from_panel

ROLES = RolesConfig().present()

PAPER_CASE = {
    "name": "paper-case",
    "site": {"latitude": 40.0, "longitude": 14.25, "timezone": "Europe/Rome"},
    "window": {"date": "2025-01-21", "start": "10:00", "duration": 120},
    "plant": {"orientation": "NS", "tube_height": 3.0},
    "mirror": {"distance": 0.0, "axis": "secondary"},
}


@pytest.fixture(scope="module")
def paper_inputs():
    return prepare_inputs(validate_scenario(PAPER_CASE))


def test_step_instants_are_where_the_sun_puts_the_reference_on_a_half_step(paper_inputs):
    scenario = validate_scenario(PAPER_CASE)
    start = paper_inputs.window_start
    assert len(paper_inputs.schedule) >= 5
    # evaluate the geometry (pvlib SPA) directly at the found instants, not the interpolant
    instants = start + pd.to_timedelta(np.concatenate([[0.0], paper_inputs.schedule.times]), unit="s")
    panel = panel_angle_reference(instants, scenario.site.to_site(), scenario.plant.to_plant(), 0.0).to_numpy()
    rotor = rotor_angle_from_panel(panel[1:], panel[0], 2.5e-3, 0.3)
    half_steps = (paper_inputs.schedule.indices - 0.5) * np.pi / 100  # rising: crossing below the new index
    np.testing.assert_allclose(rotor, half_steps, atol=1e-6)


def test_reference_starts_at_zero_rotor_angle_and_follows_the_transmission(paper_inputs):
    assert paper_inputs.rotor_angle_ref[0] == 0.0
    panel = paper_inputs.panel_angle_ref
    expected = 0.3 / 2.5e-3 * (np.tan(panel) - np.tan(panel[0]))  # [paper], eq. 14
    np.testing.assert_allclose(paper_inputs.rotor_angle_ref, expected, rtol=1e-12, atol=1e-15)


def test_signals_switch_at_the_steps(paper_inputs):
    i_a = next(s for s in _signals(paper_inputs, ROLES) if s.name == "i_a_ref")
    np.testing.assert_array_equal(i_a.times, paper_inputs.schedule.times)
    assert i_a.values[0] == 5.5  # Table 1 step 1, rated current
    implied = paper_inputs.implied_parameters
    assert {k: implied[k] for k in ("current_a_start", "current_b_start")} == {
        "current_a_start": 5.5,
        "current_b_start": 0.0,
    }


def test_output_grid_is_regular_plus_fine_after_steps():
    grid = output_grid(10.0, 1.0, np.array([2.5]), step_detail=0.01, step_interval=0.002)
    expected = np.concatenate([np.arange(0, 11.0), 2.5 + np.arange(0, 0.01, 0.002)])
    np.testing.assert_allclose(grid, np.unique(expected))


def test_no_step_detail_is_the_regular_grid_alone_and_a_negative_one_is_refused():
    np.testing.assert_array_equal(output_grid(10.0, 1.0, np.array([2.5]), 0.0, 0.002), np.arange(0, 11.0))
    window = {**PAPER_CASE["window"], "duration": 10}
    scenario = validate_scenario({**PAPER_CASE, "window": window, "output": {"interval": 1.0, "step_detail": 0}})
    inputs = prepare_inputs(scenario)
    assert len(inputs.schedule.times) > 0  # steps in the window, none with a fine grid after it
    np.testing.assert_array_equal(inputs.output_times, np.arange(0, 11.0))
    with pytest.raises(InputError, match="step_detail"):
        validate_scenario({**PAPER_CASE, "window": window, "output": {"step_detail": -0.01}})


def test_wind_signal_only_where_there_is_an_input_for_it():
    without_input = {role: target for role, target in ROLES.items() if role != "wind_moment"}
    calm = prepare_inputs(validate_scenario({**PAPER_CASE, "window": {**PAPER_CASE["window"], "duration": 10}}))
    assert [s.name for s in _signals(calm, without_input)] == ["i_a_ref", "i_b_ref"]
    windy = {**PAPER_CASE, "window": {**PAPER_CASE["window"], "duration": 10}, "wind": {"moment": 20.0}}
    assert [s.values[0] for s in _signals(prepare_inputs(validate_scenario(windy)), ROLES) if s.name == "m_ext"] == [
        20.0
    ]
    with pytest.raises(InputError, match="wind_moment"):
        _signals(prepare_inputs(validate_scenario(windy)), without_input)


@pytest.mark.parametrize("detent", [0.0, 0.14, 0.3])
def test_loaded_lag_balances_the_wind_with_the_phase_and_the_detent_torque(detent):
    # the panel's equilibrium at the start: g (k_e i sin(N_c delta) + T_d sin(4 N_c delta)) = M_ext ([9] with the
    # detent torque, [10], [15]), i = K I / (K + R) the held current; checked by substituting the lag back
    from heliostep.drive.inputs import loaded_lag

    wind, current, panel = 110.0, 2.0, 0.45
    case = {**PAPER_CASE, "wind": {"moment": wind}, "parameters": {"motor": {"T_d": detent}}}
    lag = loaded_lag(validate_scenario(case), current, panel)
    g = 0.3 / (2.5e-3 * np.cos(panel) ** 2)
    held = 100.0 * current / 100.1
    x = 50.0 * lag
    assert 0.0 < x < np.pi / 2
    assert g * (0.5 * held * np.sin(x) + detent * np.sin(4 * x)) == pytest.approx(wind, rel=1e-12)
    assert 0.5 * held * np.cos(x) + 4 * detent * np.cos(4 * x) > 0.0  # a stable equilibrium: it restores
