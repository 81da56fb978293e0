"""The built FMUs, each on its own: valid FMI 2.0 ME, correct equations, correct structure."""

import numpy as np
import pytest
from fmpy import read_model_description, simulate_fmu
from fmpy.validation import validate_fmu
from scipy.integrate import solve_ivp

from heliostep.cosim.fmi import ModelExchangeInstance, read_fmu
from physics_reference import (
    MOTOR_LOSSES,
    RATED_CURRENT,
    TABLE2_PANEL,
    TABLE3_MOTOR,
    ideal_current_motor,
    panel_mechanics,
    stepper_motor,
)
from shipped_models import MODELS

MOTOR_OUTPUTS = ["i_a", "i_b", "tau", "v_a", "v_b", "power"]
MECHANICS_OUTPUTS = ["theta_p", "omega_p", "theta", "omega"]


@pytest.mark.parametrize("name", MODELS)
def test_fmu_passes_fmpy_validation(fmu_paths, name):
    assert validate_fmu(str(fmu_paths[name])) == []


@pytest.mark.parametrize("name", MODELS)
def test_fmu_simulates_alone_with_fmpy_cvode(fmu_paths, name):
    result = simulate_fmu(
        str(fmu_paths[name]), fmi_type="ModelExchange", solver="CVode", stop_time=0.05, output_interval=1e-3
    )
    assert len(result) == 51
    for column in result.dtype.names:
        assert np.all(np.isfinite(result[column])), column


def test_model_description_declares_interface_units_and_descriptions(fmu_paths):
    description = read_model_description(str(fmu_paths["StepperMotor"]))
    variables = {v.name: v for v in description.modelVariables}
    assert [v.name for v in description.modelVariables if v.causality == "input"] == [
        "i_a_ref",
        "i_b_ref",
        "theta",
        "omega",
    ]
    assert variables["tau"].causality == "output" and variables["tau"].unit == "N.m"
    assert variables["L"].causality == "parameter" and variables["L"].variability == "tunable"
    assert float(variables["L"].start) == TABLE3_MOTOR["L"]
    assert "inductance" in variables["L"].description
    units = {u.name: u.baseUnit for u in description.unitDefinitions}
    assert units["V"].kg == 1 and units["V"].m == 2 and units["V"].s == -3 and units["V"].A == -1
    # the two currents are the states; their derivatives point back at them
    assert [d.variable.derivative.name for d in description.derivatives] == ["i_a", "i_b"]


def test_model_structure_gives_exact_direct_feedthrough(fmu_paths):
    info = read_fmu(fmu_paths["StepperMotor"])
    # eq. 9 with the iron loss: torque depends on the rotor angle and, through the back-EMF across the
    # magnetising resistance (k_e G_m omega), on its speed (inputs), not on the references
    assert info.output_feedthrough["tau"] == ["theta", "omega"]
    assert info.output_feedthrough["v_a"] == ["i_a_ref"]
    assert info.output_feedthrough["i_a"] == []
    mechanics = read_fmu(fmu_paths["PanelMechanics"])
    assert all(deps == [] for deps in mechanics.output_feedthrough.values())


def test_paper_panel_inertia_matches_eq_11(fmu_paths):
    # [paper], eq. 11: J_p = M/12 (l^2 + sp^2) with Table 2's M, l, sp
    t2 = TABLE2_PANEL
    j_p = t2["M"] / 12 * (t2["l"] ** 2 + t2["sp"] ** 2)
    default = read_fmu(fmu_paths["PanelMechanics"]).variable("J_p").start
    assert default == pytest.approx(j_p, rel=0.005)


# ----------------------------------------------------------------- equations at random points


def assert_relative(actual, expected, rtol=1e-9):
    """Equal to ``rtol`` relative to each column's scale (differences of large terms cancel)."""
    scale = np.abs(expected).max(axis=0)
    error = np.abs(actual - expected) / (scale + np.abs(expected))
    worst = np.unravel_index(np.argmax(error), error.shape)
    assert error.max() <= rtol, f"relative error {error.max():.3g} at {worst}: {actual[worst]} vs {expected[worst]}"


def _random_points(rng, n, bounds):
    return {name: rng.uniform(low, high, n) for name, (low, high) in bounds.items()}


def _evaluate_fmu(path, parameters, states, inputs, outputs, points):
    """Derivatives and outputs through the FMI API at each point (states and inputs set)."""
    info = read_fmu(path)
    with ModelExchangeInstance(info, "check", parameters) as inst:
        inst.setup_experiment(0.0)
        inst.enter_initialization_mode()
        inst.exit_initialization_mode()
        set_inputs = inst.writer(inputs)
        read_outputs = inst.reader(outputs)
        n = len(next(iter(points.values())))
        derivatives, values = np.zeros((n, len(states))), np.zeros((n, len(outputs)))
        # the FMU's own state order (its modelDescription's Derivatives), mapped to ``states``
        order = [states.index(name) for name in info.states] if set(info.states) == set(states) else range(len(states))
        order = list(order)
        for k in range(n):
            inst.set_states(np.array([points[states[i]][k] for i in order]))
            set_inputs([points[u][k] for u in inputs])
            derivatives[k, order] = inst.get_derivatives()
            values[k] = read_outputs()
    return derivatives, values


MOTOR_POINT_BOUNDS = {
    "i_a": (-7, 7),
    "i_b": (-7, 7),
    "i_a_ref": (-5.5, 5.5),
    "i_b_ref": (-5.5, 5.5),
    "theta": (-0.5, 0.5),
    "omega": (-20, 20),
}


@pytest.mark.parametrize(
    "name, reference, extra",
    [
        ("StepperMotor", stepper_motor, {"V_supply": 3.1, "K_current": 100.0}),
        ("StepperMotorIdealCurrent", ideal_current_motor, {"T_current": 1e-3}),
    ],
)
def test_motor_equations_match_numpy_at_random_points(fmu_paths, name, reference, extra):
    rng = np.random.default_rng(7)
    parameters = {k: TABLE3_MOTOR[k] * rng.uniform(0.8, 1.2) for k in ("L", "R", "k_e")}
    parameters["N_c"] = 50.0
    parameters.update({k: v * rng.uniform(0.8, 1.2) for k, v in extra.items()})
    # the losses at sizes that show: an iron-loss conductance of 0.2 S (R_m = 5 ohm) brakes by up to
    # k_e^2 G_m |omega| = 1 N.m at 20 rad/s, beside the detent torque's 0.14 N.m
    parameters.update(G_m=0.2 * rng.uniform(0.5, 1.5), T_d=0.14 * rng.uniform(0.5, 1.5))
    points = _random_points(rng, 200, MOTOR_POINT_BOUNDS)
    derivatives, outputs = _evaluate_fmu(
        fmu_paths[name], parameters, ["i_a", "i_b"], ["i_a_ref", "i_b_ref", "theta", "omega"], MOTOR_OUTPUTS, points
    )
    di_a, di_b, tau, v_a, v_b, power = reference(
        points["i_a"],
        points["i_b"],
        points["i_a_ref"],
        points["i_b_ref"],
        points["theta"],
        points["omega"],
        **parameters,
    )
    assert_relative(derivatives, np.column_stack([di_a, di_b]))
    expected = np.column_stack([points["i_a"], points["i_b"], tau, v_a, v_b, power])
    assert_relative(outputs, expected)


@pytest.mark.parametrize("name, small_angle", [("PanelMechanics", False), ("PanelMechanicsSmallAngle", True)])
def test_mechanics_equations_match_numpy_at_random_points(fmu_paths, name, small_angle):
    rng = np.random.default_rng(11)
    parameters = {"J_p": 3.37, "J_m": 1.4e-4, "b": 6500.0, "r": 2.5e-3, "s": 0.3, "B_m": 8e-4}
    parameters = {k: v * rng.uniform(0.5, 1.5) for k, v in parameters.items()}
    parameters.update(theta_p_start=0.3, theta_start=2.0)
    points = _random_points(
        rng, 200, {"theta_p": (-1.0, 1.0), "omega_p": (-0.01, 0.01), "tau": (-3, 3), "m_ext": (-50, 50)}
    )
    derivatives, outputs = _evaluate_fmu(
        fmu_paths[name], parameters, ["theta_p", "omega_p"], ["tau", "m_ext"], MECHANICS_OUTPUTS, points
    )
    dtheta_p, domega_p, theta, omega = panel_mechanics(
        points["theta_p"], points["omega_p"], points["tau"], points["m_ext"], small_angle=small_angle, **parameters
    )
    assert_relative(derivatives, np.column_stack([dtheta_p, domega_p]))
    expected = np.column_stack([points["theta_p"], points["omega_p"], theta, omega])
    assert_relative(outputs, expected)


def test_karnopp_mechanics_match_numpy_sticking_and_slipping(fmu_paths):
    # rotor speeds g omega_p within and beyond Karnopp's band w_s = 0.01 rad/s, torques below and above what
    # friction holds (T_c = 0.08 N.m): every branch of the stick-slip law
    rng = np.random.default_rng(5)
    parameters = {"J_p": 3.37, "J_m": 1.4e-4, "b": 0.0, "r": 2.5e-3, "s": 0.3, "B_m": 8e-4}
    parameters.update(theta_p_start=0.3, theta_start=2.0)
    points = _random_points(
        rng, 400, {"theta_p": (-1.0, 1.0), "omega_p": (-2e-4, 2e-4), "tau": (-0.2, 0.2), "m_ext": (-5, 5)}
    )
    derivatives, outputs = _evaluate_fmu(
        fmu_paths["PanelMechanicsKarnopp"],
        parameters,
        ["theta_p", "omega_p"],
        ["tau", "m_ext"],
        MECHANICS_OUTPUTS,
        points,
    )
    dtheta_p, domega_p, theta, omega = panel_mechanics(
        points["theta_p"], points["omega_p"], points["tau"], points["m_ext"], karnopp=True, **parameters
    )
    sticking = np.abs(omega) < 1e-2
    assert 50 < sticking.sum() < 350  # both branches are visited
    assert_relative(derivatives, np.column_stack([dtheta_p, domega_p]))
    assert_relative(outputs, np.column_stack([points["theta_p"], points["omega_p"], theta, omega]))


def test_drive_system_equations_match_numpy_at_random_points(fmu_paths):
    rng = np.random.default_rng(3)
    motor = {**TABLE3_MOTOR, "K_current": 100.0}
    mechanics = {"J_p": 3.37, "J_m": 1.4e-4, "b": 0.0, "r": 2.5e-3, "s": 0.3, "theta_p_start": 0.0, "theta_start": 0.0}
    points = _random_points(
        rng,
        100,
        {
            "theta_p": (-0.8, 0.8),
            "omega_p": (-0.01, 0.01),
            "i_a": (-6, 6),
            "i_b": (-6, 6),
            "i_a_ref": (-5.5, 5.5),
            "i_b_ref": (-5.5, 5.5),
            "m_ext": (-20, 20),
        },
    )
    states = ["mechanics.theta_p", "mechanics.omega_p", "motor.i_a", "motor.i_b"]
    renamed = {
        "mechanics.theta_p": points["theta_p"],
        "mechanics.omega_p": points["omega_p"],
        "motor.i_a": points["i_a"],
        "motor.i_b": points["i_b"],
        **points,
    }
    derivatives, outputs = _evaluate_fmu(
        fmu_paths["DriveSystem"], {}, states, ["i_a_ref", "i_b_ref", "m_ext"], ["motor.tau", "mechanics.theta"], renamed
    )
    dtheta_p, _, theta, omega = panel_mechanics(points["theta_p"], points["omega_p"], 0.0, 0.0, **mechanics)
    di_a, di_b, tau, *_ = stepper_motor(
        points["i_a"], points["i_b"], points["i_a_ref"], points["i_b_ref"], theta, omega, **motor
    )
    _, domega_p, _, _ = panel_mechanics(points["theta_p"], points["omega_p"], tau, points["m_ext"], **mechanics)
    expected = np.column_stack([dtheta_p, domega_p, di_a, di_b])
    assert_relative(derivatives, expected)
    assert_relative(outputs, np.column_stack([tau, theta]))


# ----------------------------------------------------------------- step responses vs Radau


def test_outputs_on_the_states_alone_are_read_without_the_new_input_and_stay_right(fmu_paths):
    """The master's order on every evaluation: states set, the angle and speed read, then a new
    torque set and the derivatives read. The C layer computes the outputs that depend on no
    input by themselves (model_state_part: the mechanics' g, theta, omega, friction and
    der(theta_p), not der(omega_p)), and keeps them over a new input: every value at every step
    of that order equals the numpy model's."""
    header = __import__("zipfile").ZipFile(fmu_paths["PanelMechanics"]).read("sources/model.h").decode()
    assert "#define N_STATE_PART 5" in header  # everything but der(omega_p), which needs the torque
    parameters = {"J_p": 3.37, "J_m": 1.4e-4, "b": 0.0, "r": 2.5e-3, "s": 0.3, "theta_p_start": 0.3, "theta_start": 2.0}
    rng = np.random.default_rng(3)
    info = read_fmu(fmu_paths["PanelMechanics"])
    with ModelExchangeInstance(info, "order", parameters) as inst:
        inst.setup_experiment(0.0)
        inst.enter_initialization_mode()
        inst.exit_initialization_mode()
        inst.enter_continuous_time_mode()
        read = inst.reader(["theta", "omega", "omega_p"])
        set_torque = inst.writer(["tau", "m_ext"])
        order = [info.states.index(name) for name in ("theta_p", "omega_p")]
        for _ in range(50):
            theta_p, omega_p, torque = rng.uniform(-1, 1), rng.uniform(-0.01, 0.01), rng.uniform(-3, 3)
            x = np.zeros(2)
            x[order] = theta_p, omega_p
            inst.set_states(x)
            _, _, theta, omega = panel_mechanics(theta_p, omega_p, 0.0, 0.0, **parameters)
            np.testing.assert_allclose(read()[:2], [theta, omega], rtol=1e-12)  # before the new input
            set_torque([torque, 5.0])
            np.testing.assert_allclose(read(), [theta, omega, omega_p], rtol=1e-12)  # kept over it
            dtheta_p, domega_p, _, _ = panel_mechanics(theta_p, omega_p, torque, 5.0, **parameters)
            np.testing.assert_allclose(inst.get_derivatives()[order], [dtheta_p, domega_p], rtol=1e-9)


@pytest.mark.parametrize(
    ("name", "rest"), [("PanelMechanics", 1), ("PanelMechanicsKarnopp", 3), ("PanelMechanicsSmallAngle", 1)]
)
def test_the_rest_after_the_state_part_is_the_full_evaluation_bit_for_bit(fmu_paths, name, rest):
    """After the state part (the angle read first, as the master does), the C layer computes only the
    rest (model_rest: der(omega_p), and the Karnopp model's stick-slip variables) from the state part's
    values; a second instance, never asked for the state part, evaluates everything at once
    (model_eval). Every derivative and output is the same bit for bit, at 200 random states and inputs
    (the panel swinging and at rest, the rotor above and below the friction's regularisation speed)."""
    header = __import__("zipfile").ZipFile(fmu_paths[name]).read("sources/model.h").decode()
    assert f"#define N_REST {rest}\n" in header
    info = read_fmu(fmu_paths[name])
    outputs = list(info.outputs)
    rng = np.random.default_rng(7)
    with (
        ModelExchangeInstance(info, "state part first", {}) as first,
        ModelExchangeInstance(info, "all at once", {}) as whole,
    ):
        for inst in (first, whole):
            inst.setup_experiment(0.0)
            inst.enter_initialization_mode()
            inst.exit_initialization_mode()
            inst.enter_continuous_time_mode()
        angle = first.reader(["theta"])
        set_inputs = {inst: inst.writer(["tau", "m_ext"]) for inst in (first, whole)}
        read_all = {inst: inst.reader(outputs) for inst in (first, whole)}
        order = [info.states.index(s) for s in ("theta_p", "omega_p")]
        for k in range(200):
            x = np.zeros(len(info.states))
            x[order] = rng.uniform(-1.0, 1.0), rng.uniform(-0.02, 0.02) * (k % 2) * 10.0 ** -rng.integers(0, 4)
            inputs = [rng.uniform(-3.0, 3.0), rng.uniform(-200.0, 200.0)]
            for inst in (first, whole):
                inst.set_time(1e-3 * k)
                inst.set_states(x)
            angle()  # the state part, before the new inputs
            for inst in (first, whole):
                set_inputs[inst](inputs)
            derivatives = first.get_derivatives().tobytes(), whole.get_derivatives().tobytes()
            assert derivatives[0] == derivatives[1], k
            assert read_all[first]().tobytes() == read_all[whole]().tobytes(), k


def _step_input(names, values, stop_time):
    dtype = [("time", float)] + [(n, float) for n in names]
    return np.array([(0.0, *values), (stop_time, *values)], dtype=dtype)


def test_phase_current_step_with_rotor_held_matches_radau(fmu_paths):
    theta_held = 0.004  # [rad], rotor held off a detent so the torque is not zero
    motor = {**TABLE3_MOTOR, "K_current": 100.0}
    stop_time = 0.01
    signals = _step_input(["i_a_ref", "i_b_ref", "theta", "omega"], [RATED_CURRENT, 0.0, theta_held, 0.0], stop_time)
    result = simulate_fmu(
        str(fmu_paths["StepperMotor"]),
        fmi_type="ModelExchange",
        solver="CVode",
        stop_time=stop_time,
        output_interval=1e-4,
        input=signals,
        relative_tolerance=1e-8,
        output=["i_a", "i_b", "tau"],
    )

    def rhs(t, y):
        di_a, di_b, *_ = stepper_motor(y[0], y[1], RATED_CURRENT, 0.0, theta_held, 0.0, **motor)
        return [di_a, di_b]

    radau = solve_ivp(
        rhs, (0, stop_time), [0.0, 0.0], method="Radau", t_eval=result["time"], rtol=1e-10, atol=1e-12, max_step=1e-5
    )
    np.testing.assert_allclose(result["i_a"], radau.y[0], atol=2e-4 * RATED_CURRENT)
    np.testing.assert_allclose(result["i_b"], radau.y[1], atol=1e-9)
    # first principles: the current rises at (dV - R i)/L while the chopper is saturated ...
    early = result["time"] == pytest.approx(1e-3)
    assert result["i_a"][early] == pytest.approx(3.1 / 1.8e-3 * 1e-3, rel=0.05)
    # ... and settles at K I / (K + R), the proportional loop's steady state
    assert result["i_a"][-1] == pytest.approx(100 * RATED_CURRENT / 100.1, rel=1e-6)
    # ... and the torque is eq. 9's of phase A with the detent torque's pull toward the full step
    detent = MOTOR_LOSSES["T_d"] * np.sin(4 * 50 * theta_held)
    assert result["tau"][-1] == pytest.approx(-0.5 * result["i_a"][-1] * np.sin(50 * theta_held) - detent, rel=1e-6)


def test_torque_step_into_mechanics_matches_radau(fmu_paths):
    mechanics = {"J_p": 3.37, "J_m": 1.4e-4, "b": 0.0, "r": 2.5e-3, "s": 0.3, "theta_p_start": 0.2, "theta_start": 0.0}
    stop_time = 2.0
    signals = _step_input(["tau", "m_ext"], [0.5, 2.0], stop_time)
    result = simulate_fmu(
        str(fmu_paths["PanelMechanics"]),
        fmi_type="ModelExchange",
        solver="CVode",
        stop_time=stop_time,
        output_interval=0.01,
        input=signals,
        relative_tolerance=1e-9,
        start_values={"theta_p_start": 0.2},
        output=["theta_p", "omega_p", "theta"],
    )

    def rhs(t, y):
        dtheta_p, domega_p, _, _ = panel_mechanics(y[0], y[1], 0.5, 2.0, **mechanics)
        return [dtheta_p, domega_p]

    radau = solve_ivp(rhs, (0, stop_time), [0.2, 0.0], method="Radau", t_eval=result["time"], rtol=1e-11, atol=1e-14)
    np.testing.assert_allclose(result["theta_p"], radau.y[0], rtol=1e-6, atol=1e-10)
    np.testing.assert_allclose(result["omega_p"], radau.y[1], rtol=1e-5, atol=1e-10)
    rotor = mechanics["s"] / mechanics["r"] * (np.tan(radau.y[0]) - np.tan(0.2))
    np.testing.assert_allclose(result["theta"], rotor, rtol=1e-5, atol=1e-8)
