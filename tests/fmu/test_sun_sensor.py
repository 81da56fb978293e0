"""models/SunSensor.mo built and run: the differential two-cell sun sensor against its formula written here.

Each case holds the master's inputs constant for one second and reads the outputs in its middle; the
expected signal is (A - B)/(A + B) + noise with A = dni a + diffuse_view dhi, B = dni (1 - a) +
diffuse_view dhi, a = clamp(0.5 + 0.5 tan(e)/tan(fov), 0, 1), e = k_ray (theta_ref - theta_p + offset),
0 in the dark (A + B not above the threshold).
"""

from __future__ import annotations

import hashlib
import math

import numpy as np
import pytest
from fmpy import read_model_description

from heliostep.cli import main
from heliostep.cosim import Connection, CoSimulation, PiecewiseConstant, read_fmu

#: The FMU's defaults, as models/SunSensor.mo gives them (the SSOC-D60 preset's values).
DEFAULTS = {
    "k_ray": 2.0,
    "fov": math.radians(60.0),
    "offset": 0.0,
    "threshold": 120.0,
    "diffuse_view": 2.0 / math.pi * math.sin(math.radians(60.0)) * math.atan(math.sin(math.radians(60.0))),
}
INPUTS = ("theta_p", "theta_ref", "dni", "dhi", "noise")
CLEAR = {"theta_p": 0.3, "dni": 800.0, "dhi": 0.0, "noise": 0.0}


def expected(case: dict, parameters: dict | None = None) -> tuple[float, float, float]:
    """(signal, irradiance, lit) of the sensor, from its definition (valid for |e| < pi/2)."""
    p = {**DEFAULTS, **(parameters or {})}
    e = p["k_ray"] * (case["theta_ref"] - case["theta_p"] + p["offset"])
    a = min(max(0.5 + 0.5 * math.tan(e) / math.tan(p["fov"]), 0.0), 1.0)
    cell_a = case["dni"] * a + p["diffuse_view"] * case["dhi"]
    cell_b = case["dni"] * (1.0 - a) + p["diffuse_view"] * case["dhi"]
    total = cell_a + cell_b
    if not total > p["threshold"]:
        return 0.0, total, 0.0
    return (cell_a - cell_b) / total + case["noise"], total, 1.0


def run_cases(fmu_paths, cases: list[dict], parameters: dict | None = None) -> np.ndarray:
    """The sensor FMU run through the master, one case per second: rows (signal, irradiance, lit)."""
    times = np.arange(1.0, len(cases))
    inputs = [
        PiecewiseConstant(name, f"sensor.{name}", times, np.array([case[name] for case in cases], dtype=float))
        for name in INPUTS
    ]
    system = CoSimulation(
        {"sensor": read_fmu(fmu_paths["SunSensor"])}, inputs=inputs, parameters={"sensor": parameters or {}}
    )
    result = system.simulate(0.0, float(len(cases)), np.arange(len(cases)) + 0.5)
    assert result.statistics["states"] == 0 and result.statistics["compiled_rhs"]
    rows = result.trace[np.isin(result.trace["time"], np.arange(len(cases)) + 0.5)]
    return rows[["sensor.signal", "sensor.irradiance", "sensor.lit"]].to_numpy()


def errors_case(errors, **inputs) -> list[dict]:
    """Cases at the panel's pointing errors theta_ref - theta_p [rad]."""
    base = {**CLEAR, **inputs}
    return [{**base, "theta_ref": base["theta_p"] + error} for error in errors]


def check(rows: np.ndarray, cases: list[dict], parameters: dict | None = None) -> None:
    for row, case in zip(rows, cases, strict=True):
        assert tuple(row) == pytest.approx(expected(case, parameters), rel=1e-12, abs=1e-14), case


def test_the_interface_names_units_and_defaults(fmu_paths):
    description = read_model_description(str(fmu_paths["SunSensor"]))
    variables = {v.name: v for v in description.modelVariables}
    assert [v.name for v in description.modelVariables if v.causality == "input"] == list(INPUTS)
    assert [v.name for v in description.modelVariables if v.causality == "output"] == ["signal", "irradiance", "lit"]
    assert {name: float(variables[name].start) for name in DEFAULTS} == pytest.approx(DEFAULTS, rel=1e-15)
    units = {v.name: v.unit for v in description.modelVariables if v.causality != "local"}
    assert units == {
        **{"k_ray": "1", "fov": "rad", "offset": "rad", "threshold": "W/m2", "diffuse_view": "1"},
        **{"theta_p": "rad", "theta_ref": "rad", "dni": "W/m2", "dhi": "W/m2", "noise": "1"},
        **{"signal": "1", "irradiance": "W/m2", "lit": "1"},
    }
    assert description.derivatives == [] and description.numberOfContinuousStates == 0  # outputs algebraic in inputs
    assert all(variables[name].description for name in (*DEFAULTS, *INPUTS))


@pytest.mark.parametrize("dhi", [0.0, 150.0])
def test_inside_the_field_of_view_the_signal_is_linear_in_tan_e(fmu_paths, dhi):
    # panel errors up to +-0.5 rad: sensor angles up to +-1 rad, inside the +-60 deg (1.047 rad) field of view
    cases = errors_case([-0.5, -0.2, -0.05, -1e-4, 0.0, 1e-4, 0.01, 0.1, 0.3, 0.5], dhi=dhi)
    rows = run_cases(fmu_paths, cases)
    check(rows, cases)
    dilution = 800.0 / (800.0 + 2 * DEFAULTS["diffuse_view"] * dhi)
    for row, case in zip(rows, cases, strict=True):  # the same, as the slit's law: tan(e)/tan(fov), diluted
        e = 2.0 * (case["theta_ref"] - case["theta_p"])
        assert row[0] == pytest.approx(dilution * math.tan(e) / math.tan(DEFAULTS["fov"]), rel=1e-12, abs=1e-15)


def test_outside_the_field_of_view_the_signal_saturates_with_the_error_s_sign(fmu_paths):
    # sensor angles 1.1 and 1.5 rad (past 60 deg, below 90 deg), then 2.4 and 3.0 rad: a panel far off,
    # where tan(e) would turn over, still reads full scale toward the reference
    cases = errors_case([0.55, 0.75, -0.55, -0.75, 1.2, 1.5, -1.2, -1.5])
    rows = run_cases(fmu_paths, cases)
    check(rows[:4], cases[:4])
    assert list(rows[:, 0]) == [1.0, 1.0, -1.0, -1.0, 1.0, 1.0, -1.0, -1.0]
    assert list(rows[:, 2]) == [1.0] * 8


def test_the_signal_is_positive_when_the_panel_lags_the_reference(fmu_paths):
    cases = [{**CLEAR, "theta_p": p, "theta_ref": r} for p, r in ((0.1, 0.2), (-0.3, -0.25), (0.2, 0.1), (0.4, 0.4))]
    signal = run_cases(fmu_paths, cases)[:, 0]
    assert signal[0] > 0 and signal[1] > 0  # theta_ref > theta_p: step toward positive signal
    assert signal[2] < 0 and signal[3] == 0.0


def test_the_offset_shifts_the_zero_by_minus_the_offset(fmu_paths):
    offset = 0.0123
    errors = [-offset - 0.1, -offset, -offset + 0.05, 0.0]
    cases = errors_case(errors)
    shifted = run_cases(fmu_paths, cases, {"offset": offset})
    check(shifted, cases, {"offset": offset})
    assert shifted[1, 0] == pytest.approx(0.0, abs=1e-15)  # balanced at theta_ref - theta_p = -offset
    plain = run_cases(fmu_paths, errors_case([error + offset for error in errors]))
    np.testing.assert_allclose(shifted[:, 0], plain[:, 0], rtol=1e-12, atol=1e-15)


def test_diffuse_light_dilutes_the_difference(fmu_paths):
    cases = errors_case([0.1] * 4, dni=600.0)
    for case, dhi in zip(cases, (0.0, 100.0, 300.0, 600.0), strict=True):
        case["dhi"] = dhi
    rows = run_cases(fmu_paths, cases, {"diffuse_view": 0.25})
    check(rows, cases, {"diffuse_view": 0.25})
    np.testing.assert_allclose(rows[:, 1], 600.0 + 2 * 0.25 * np.array([0.0, 100.0, 300.0, 600.0]), rtol=1e-15)
    np.testing.assert_allclose(rows[:, 0], rows[0, 0] * 600.0 / rows[:, 1], rtol=1e-12)


def test_below_the_dark_threshold_the_signal_is_zero_and_lit_is_zero(fmu_paths):
    cases = [
        {**CLEAR, "theta_ref": 0.5, "dni": 0.0, "dhi": 0.0, "noise": 0.02},  # night
        {**CLEAR, "theta_ref": 0.5, "dni": 60.0, "dhi": 40.0, "noise": 0.02},  # under a cloud: 91.5 W/m2
        {**CLEAR, "theta_ref": 0.5, "dni": 120.0, "dhi": 0.0},  # at the threshold: dark
        {**CLEAR, "theta_ref": 0.5, "dni": 121.0, "dhi": 0.0},  # just above it: lit
    ]
    rows = run_cases(fmu_paths, cases)
    check(rows, cases)
    assert list(rows[:, 0][:3]) == [0.0, 0.0, 0.0] and list(rows[:, 2]) == [0.0, 0.0, 0.0, 1.0]
    rows = run_cases(fmu_paths, cases[1:2], {"threshold": 50.0})
    assert rows[0, 2] == 1.0 and rows[0, 0] == pytest.approx(expected(cases[1], {"threshold": 50.0})[0], rel=1e-12)


def test_the_noise_is_added_to_the_signal(fmu_paths):
    noise = [0.0, 0.03, -0.07, 0.5]
    cases = [{**CLEAR, "theta_ref": 0.35, "dhi": 80.0, "noise": n} for n in noise]
    rows = run_cases(fmu_paths, cases)
    check(rows, cases)
    np.testing.assert_allclose(rows[:, 0] - rows[0, 0], noise, rtol=0, atol=1e-15)


def test_the_sensor_beside_the_panel_mechanics_follows_the_panel_angle(fmu_paths):
    """SunSensor and PanelMechanics in one master (mechanics.theta_p -> sensor.theta_p): a torque turns the
    panel through the reference, and the sensor's signal at every output is the formula's of the panel angle
    the trace holds, positive while the panel lags, negative once past."""
    theta_ref = 0.05

    def master(name, target, value):
        return PiecewiseConstant(name, target, np.array([]), np.array([value]))

    system = CoSimulation(
        {"mechanics": read_fmu(fmu_paths["PanelMechanics"]), "sensor": read_fmu(fmu_paths["SunSensor"])},
        [Connection("mechanics.theta_p", "sensor.theta_p")],
        inputs=[
            master("tau", "mechanics.tau", 0.2),
            master("m_ext", "mechanics.m_ext", 0.0),
            master("theta_ref", "sensor.theta_ref", theta_ref),
            master("dni", "sensor.dni", 800.0),
            master("dhi", "sensor.dhi", 100.0),
            master("noise", "sensor.noise", 0.0),
        ],
    )
    result = system.simulate(0.0, 0.4, np.linspace(0.0, 0.4, 41))
    assert result.statistics["compiled_rhs"] and result.statistics["states"] == 2
    trace = result.trace
    theta_p, signal = trace["mechanics.theta_p"].to_numpy(), trace["sensor.signal"].to_numpy()
    assert theta_p[0] == 0.0 and theta_p[-1] > 0.15 and np.all(np.diff(theta_p) > 0)
    for angle, value in zip(theta_p, signal, strict=True):
        case = {"theta_p": angle, "theta_ref": theta_ref, "dni": 800.0, "dhi": 100.0, "noise": 0.0}
        assert value == pytest.approx(expected(case)[0], rel=1e-12, abs=1e-14)
    assert np.all(np.diff(signal) < 0) and signal[0] > 0 > signal[-1]
    assert np.all(np.sign(signal) == np.sign(theta_ref - theta_p))


def test_building_the_sensor_twice_gives_identical_fmus(tmp_path, monkeypatch, capsys):
    digests = []
    for name in ("a", "b"):
        monkeypatch.setenv("HELIOSTEP_FMUS", str(tmp_path / f"cache-{name}"))
        assert main(["build-fmus", "--model", "SunSensor", "--out", str(tmp_path / name)]) == 0
        digests.append(hashlib.sha256((tmp_path / name / "SunSensor.fmu").read_bytes()).hexdigest())
    assert capsys.readouterr().err.count("heliostep: building SunSensor.fmu (first use") == 2
    assert digests[0] == digests[1]
