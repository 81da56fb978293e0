"""The motor FMU's driver: its bus voltage ``V_supply`` and current-loop gain ``K_current`` against the closed
form of the averaged chopper with the rotor locked (theta = omega = 0: no back-EMF), run by fmpy.

A step of the reference from 0 to I: while the loop asks for more than the bus, K (I - i) > V, the winding sees
the full bus, L di/dt = V - R i, so i = (V / R) (1 - exp(-t R / L)) until i_1 = I - V / K at
t_1 = (L / R) ln(V / (V - R i_1)); then L di/dt = K (I - i) - R i, a first-order approach with
tau = L / (K + R) to the held current K I / (K + R) (the model's docstring: the paper's eqs. 7-8 with
v = clamp(K (i_ref - i), -V, V)).
"""

from __future__ import annotations

import numpy as np
import pytest
from fmpy import simulate_fmu

from physics_reference import RATED_CURRENT, TABLE3_MOTOR


def _chopper_current(t, current, bus, gain, L=TABLE3_MOTOR["L"], R=TABLE3_MOTOR["R"]):
    """The closed form above [A] at times t [s]."""
    i_1 = current - bus / gain
    t_1 = L / R * np.log(bus / (bus - R * i_1))
    held = gain * current / (gain + R)
    saturated = bus / R * (1.0 - np.exp(-t * R / L))
    linear = held + (i_1 - held) * np.exp(-(t - t_1) * (gain + R) / L)
    return np.where(t < t_1, saturated, linear), t_1


def _locked_rotor_step(fmu, bus, gain, stop):
    inputs = np.array(
        [(0.0, RATED_CURRENT, 0.0, 0.0, 0.0), (stop, RATED_CURRENT, 0.0, 0.0, 0.0)],
        dtype=[("time", float), ("i_a_ref", float), ("i_b_ref", float), ("theta", float), ("omega", float)],
    )
    return simulate_fmu(
        str(fmu),
        fmi_type="ModelExchange",
        solver="CVode",
        stop_time=stop,
        output_interval=stop / 2000,
        relative_tolerance=1e-10,
        start_values={"V_supply": bus, "K_current": gain},
        input=inputs,
        output=["i_a", "v_a"],
    )


@pytest.mark.parametrize("bus, gain", [(3.1, 100.0), (48.0, 100.0), (48.0, 25.0), (24.0, 2600.0)])
def test_the_phase_current_rises_as_the_bus_and_the_loop_gain_say(fmu_paths, bus, gain):
    stop = 0.01 if bus < 10 else 0.001
    result = _locked_rotor_step(fmu_paths["StepperMotor"], bus, gain, stop)
    expected, t_1 = _chopper_current(result["time"], RATED_CURRENT, bus, gain)
    np.testing.assert_allclose(result["i_a"], expected, atol=2e-4 * RATED_CURRENT)
    saturated = result["time"] < 0.9 * t_1
    assert np.all(result["v_a"][saturated] == pytest.approx(bus))  # the whole bus while the loop saturates
    held = gain * RATED_CURRENT / (gain + TABLE3_MOTOR["R"])  # what the loop holds: below I by R / (K + R)
    assert result["i_a"][-1] == pytest.approx(held, rel=1e-5) and result["i_a"][-1] < RATED_CURRENT


def test_the_rise_to_the_reference_takes_3_5_ms_on_the_rated_3_1_v_and_0_19_ms_on_48_v():
    # the figures docs/physics.md quotes for the paper's 3.1 V and jan21-48v's bus: t_1 of the closed form
    assert _chopper_current(np.array([0.0]), RATED_CURRENT, 3.1, 100.0)[1] == pytest.approx(3.49e-3, rel=0.01)
    assert _chopper_current(np.array([0.0]), RATED_CURRENT, 48.0, 100.0)[1] == pytest.approx(1.89e-4, rel=0.01)
