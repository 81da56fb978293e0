"""The Modelica models' physics, checked from first principles through the built FMUs."""

import numpy as np
import pytest
from fmpy import simulate_fmu

from physics_reference import RATED_CURRENT, STEP_ANGLE, TABLE2_PANEL, TABLE3_MOTOR

#: Table 1 of the paper, one-phase-on: (phase A, phase B) per step.
ONE_PHASE_ON = [(1, 0), (0, -1), (-1, 0), (0, 1)]
#: Coulomb friction T_c on the rotor stops it within T_c / k of its detent, k = k_e I N_c [rad].
STICK_BAND = 0.08 / (0.5 * RATED_CURRENT * 50)


def _sequence_input(patterns, step_period, stop_time):
    """Reference currents that switch to the next pattern every ``step_period`` seconds."""
    rows = []
    for k, (a, b) in enumerate(patterns):
        t0 = k * step_period
        t1 = (k + 1) * step_period if k + 1 < len(patterns) else stop_time
        rows += [(t0, a * RATED_CURRENT, b * RATED_CURRENT, 0.0), (t1, a * RATED_CURRENT, b * RATED_CURRENT, 0.0)]
    return np.array(rows, dtype=[("time", float), ("i_a_ref", float), ("i_b_ref", float), ("m_ext", float)])


def _simulate_drive(path, patterns, step_period, stop_time, interval=1e-4, **kwargs):
    return simulate_fmu(
        str(path),
        fmi_type="ModelExchange",
        solver="CVode",
        stop_time=stop_time,
        output_interval=interval,
        relative_tolerance=1e-8,
        input=_sequence_input(patterns, step_period, stop_time),
        output=[
            "motor.i_a",
            "motor.i_b",
            "motor.tau",
            "motor.power",
            "mechanics.theta",
            "mechanics.omega",
            "mechanics.theta_p",
        ],
        **kwargs,
    )


def _at(result, time):
    return np.searchsorted(result["time"], time - 1e-12)


def test_one_phase_on_sequence_advances_one_step_angle_per_step(fmu_paths):
    # Table 1, 1 -> 2 -> 3 -> 4 -> 1: the stable position moves by pi/(2 N_c) = 1.8 deg each time
    period = 0.1
    patterns = ONE_PHASE_ON + ONE_PHASE_ON[:1]
    result = _simulate_drive(fmu_paths["DriveSystem"], patterns, period, len(patterns) * period)
    for k in range(len(patterns)):
        settled = result["mechanics.theta"][_at(result, (k + 1) * period) - 1]
        assert settled == pytest.approx(k * STEP_ANGLE, abs=STICK_BAND), f"after step {k}"


def test_reversed_sequence_turns_the_other_way(fmu_paths):
    period = 0.1
    patterns = [ONE_PHASE_ON[0], ONE_PHASE_ON[3], ONE_PHASE_ON[2]]
    result = _simulate_drive(fmu_paths["DriveSystem"], patterns, period, 3 * period)
    assert result["mechanics.theta"][-1] == pytest.approx(-2 * STEP_ANGLE, abs=STICK_BAND)


def test_single_step_rings_down_under_coulomb_friction_and_moves_the_panel(fmu_paths):
    period = 0.2
    result = _simulate_drive(fmu_paths["DriveSystem"], ONE_PHASE_ON[:2], period, 2 * period, interval=2e-5)
    after = result["time"] >= period
    theta = result["mechanics.theta"][after]
    # no viscous damping: the step overshoots and rings (the paper's undamped detent) ...
    assert theta.max() > 1.05 * STEP_ANGLE
    # ... and Coulomb friction T_c on the rotor takes 2 T_c / k off the amplitude every half
    # cycle (k = k_e I N_c, period 2 pi sqrt(J / k)), so it is within 5 % of a step after
    # (overshoot / (2 T_c / k)) half cycles, with margin; it ends within T_c / k of the detent
    k = 0.5 * RATED_CURRENT * 50
    J = 1.4e-4 + TABLE2_PANEL["J_p"] * (TABLE2_PANEL["r"] / TABLE2_PANEL["s"]) ** 2
    half_cycles = (theta.max() - STEP_ANGLE) / (2 * 0.08 / k)
    late = result["time"][after] >= period + 1.5 * half_cycles * np.pi * np.sqrt(J / k)
    assert np.all(np.abs(theta[late] - STEP_ANGLE) <= 0.05 * STEP_ANGLE)
    assert abs(theta[-1] - STEP_ANGLE) <= 1.01 * 0.08 / k
    # eqs. 12-14: one rotor step turns the panel by atan((r/s) * step) from 0
    r, s = TABLE2_PANEL["r"], TABLE2_PANEL["s"]
    assert result["mechanics.theta_p"][-1] == pytest.approx(np.arctan(r / s * theta[-1]), rel=1e-6)


def test_motor_starts_at_the_current_its_loop_holds(fmu_paths):
    # L di/dt = K (i_ref - i) - R i = 0 at i = K i_ref / (K + R): the first instant is a steady state
    result = simulate_fmu(
        str(fmu_paths["StepperMotor"]),
        fmi_type="ModelExchange",
        solver="CVode",
        stop_time=0.01,
        output_interval=1e-3,
        relative_tolerance=1e-9,
        start_values={"i_a_start": RATED_CURRENT},
        input=np.array(
            [(0.0, RATED_CURRENT, 0.0, 0.0, 0.0), (0.01, RATED_CURRENT, 0.0, 0.0, 0.0)],
            dtype=[("time", float), ("i_a_ref", float), ("i_b_ref", float), ("theta", float), ("omega", float)],
        ),
        output=["i_a"],
    )
    np.testing.assert_allclose(result["i_a"], 100 * RATED_CURRENT / 100.1, rtol=1e-12)


def test_energy_balance_over_a_step(fmu_paths):
    # electrical energy in = resistive loss + mechanical work + change of magnetic energy
    period = 0.05
    result = _simulate_drive(fmu_paths["DriveSystem"], ONE_PHASE_ON[:2], period, 2 * period, interval=1e-5)
    t = result["time"]
    i_a, i_b = result["motor.i_a"], result["motor.i_b"]
    energy_in = np.trapezoid(result["motor.power"], t)
    resistive = np.trapezoid(TABLE3_MOTOR["R"] * (i_a**2 + i_b**2), t)
    mechanical = np.trapezoid(result["motor.tau"] * result["mechanics.omega"], t)
    magnetic = TABLE3_MOTOR["L"] / 2 * ((i_a[-1] ** 2 + i_b[-1] ** 2) - (i_a[0] ** 2 + i_b[0] ** 2))
    assert mechanical > 0.01 * energy_in  # the step did work: the balance is not trivial
    assert resistive + mechanical + magnetic == pytest.approx(energy_in, rel=0.01)


def test_small_angle_mechanics_agree_with_exact_form_near_zero(fmu_paths):
    # at theta_p ~ 0, cos^2 theta_p ~ 1: the paper's eq. 10 and the exact form coincide
    stop = 0.5
    signals = np.array([(0.0, 0.3, 0.0), (stop, 0.3, 0.0)], dtype=[("time", float), ("tau", float), ("m_ext", float)])
    runs = [
        simulate_fmu(
            str(fmu_paths[name]),
            fmi_type="ModelExchange",
            solver="CVode",
            stop_time=stop,
            output_interval=0.01,
            input=signals,
            relative_tolerance=1e-9,
            output=["theta_p"],
        )
        for name in ("PanelMechanics", "PanelMechanicsSmallAngle")
    ]
    exact, small = runs[0]["theta_p"], runs[1]["theta_p"]
    assert exact[-1] > 0
    # they differ at second order in theta_p (cos^2 and tan - theta): relative ~ theta_p^2
    np.testing.assert_allclose(exact, small, rtol=2 * exact.max() ** 2 + 1e-6, atol=1e-12)


def test_vanishing_current_is_evaluated_not_nan(fmu_paths):
    # a phase current decaying as exp(-t / 18 us) reaches 1e-155 A after 0.1 s; its square
    # underflows, and the Newton step's QR once returned NaN for it ("could not be solved")
    from heliostep.cosim.fmi import ModelExchangeInstance, read_fmu

    info = read_fmu(fmu_paths["StepperMotor"])
    with ModelExchangeInstance(info, "tiny", {}) as motor:
        motor.setup_experiment(0.0)
        motor.enter_initialization_mode()
        motor.exit_initialization_mode()
        motor.enter_continuous_time_mode()
        for tiny in (1e-152, 1e-155, 1e-160, 1e-300):
            motor.set_real(motor.value_references(["i_a_ref", "i_b_ref", "theta", "omega"]), [5.5, 0.0, 0.0, -tiny])
            motor.set_states(np.array([5.5 * 100 / 100.1, tiny]))
            derivatives = motor.get_derivatives()
            assert np.all(np.isfinite(derivatives)), tiny
            assert abs(derivatives[1]) < 1e-100  # nothing drives phase B
