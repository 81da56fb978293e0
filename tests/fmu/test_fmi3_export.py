"""The project's own models as FMI 3.0 Model Exchange FMUs (``heliostep build-fmus --fmi 3``):
validated by fmpy, simulated alone by fmpy like their FMI 2.0 twins, deterministic, and a C layer
that refuses calls out of FMI 3.0's state machine with fmi3Error instead of crashing."""

import hashlib
import zipfile
from pathlib import Path

import numpy as np
import pytest
from fmpy import extract, read_model_description, simulate_fmu
from fmpy.fmi1 import FMICallException
from fmpy.fmi3 import FMU3Model, fmi3Float64, fmi3ValueReference
from fmpy.validation import validate_fmu

from heliostep.cli import main
from heliostep.fmu.build import build_fmu, ensure_fmu, fmu_guid

FMI3_ERROR = 3


def _sha256(path):
    return hashlib.sha256(path.read_bytes()).hexdigest()


@pytest.fixture(scope="module")
def fmi3_cache(tmp_path_factory):
    return tmp_path_factory.mktemp("fmus3")


@pytest.mark.parametrize("model", ["StepperMotor", "PanelMechanics", "DriveSystem"])
def test_fmi3_fmu_is_valid_for_fmpy_and_says_fmi_3(model, fmi3_cache):
    path = build_fmu(model, fmi3_cache, fmi_version=3)
    assert path.name == f"{model}-fmi3.fmu"
    assert validate_fmu(str(path)) == []  # fmpy's schema and structure checks of FMI 3.0
    description = read_model_description(str(path))
    assert description.fmiVersion == "3.0"
    assert description.guid == fmu_guid(path)  # the instantiationToken
    assert description.modelExchange is not None and description.coSimulation is None
    variables = {v.name: v for v in description.modelVariables}
    assert variables["time"].causality == "independent"
    assert {v.type for v in description.modelVariables} == {"Float64"}
    units = {u.name for u in description.unitDefinitions}
    assert {v.unit for v in description.modelVariables if v.unit} <= units
    names = zipfile.ZipFile(path).namelist()
    assert f"binaries/x86_64-linux/{model}.so" in names
    assert "sources/fmi3_model_exchange.c" in names and "sources/buildDescription.xml" in names


def test_stepper_motor_model_structure_gives_the_feedthrough_by_value_reference(fmi3_cache):
    """The dependencies of StepperMotor's equations (models/StepperMotor.mo): v_a =
    sat(K (i_a_ref - i_a)), power = v_a i_a + v_b i_b, der(i_a) from v_a, i_a, omega, theta."""
    description = read_model_description(str(build_fmu("StepperMotor", fmi3_cache, fmi_version=3)))
    by_name = {v.name: v for v in description.modelVariables}
    outputs = {u.variable.name: {d.name for d in u.dependencies} for u in description.outputs}
    assert outputs["v_a"] == {"i_a", "i_a_ref"}
    assert outputs["power"] == {"i_a", "i_b", "i_a_ref", "i_b_ref"}
    assert outputs["i_a"] == {"i_a"}
    derivatives = {u.variable.name: {d.name for d in u.dependencies} for u in description.derivatives}
    assert derivatives["der(i_a)"] == {"i_a", "i_a_ref", "omega", "theta"}
    assert by_name["der(i_a)"].derivative is by_name["i_a"]
    initial = {u.variable.name for u in description.initialUnknowns}
    assert {"i_a", "i_b", "der(i_a)", "der(i_b)", "tau", "power"} <= initial


def _signals(names_and_functions, stop_time):
    t = np.linspace(0.0, stop_time, 51)
    signals = np.zeros(len(t), dtype=[("time", float)] + [(name, float) for name, _ in names_and_functions])
    signals["time"] = t
    for name, function in names_and_functions:
        signals[name] = function(t)
    return signals


INPUTS = {
    "StepperMotor": [
        ("i_a_ref", lambda t: 0.5 * np.cos(4 * t)),
        ("i_b_ref", lambda t: 0.5 * np.sin(4 * t)),
        ("theta", lambda t: 0.3 * t),
        ("omega", lambda t: 0.3 + 0 * t),
    ],
    "PanelMechanics": [("tau", lambda t: 1.5 * np.sin(5 * t)), ("m_ext", lambda t: 0.2 + 0 * t)],
}


@pytest.mark.parametrize("model", sorted(INPUTS))
def test_fmpy_simulation_of_the_fmi3_fmu_equals_the_fmi2_fmus_bit_for_bit(model, fmi3_cache):
    """Both FMUs compile the very same generated equations with the very same evaluation core,
    and fmpy drives both with the same CVODE settings and the same input samples: every
    floating-point operation is the same, so the results are equal exactly, not merely within
    the solver tolerance (a difference would be a difference in the call sequence or the layer)."""
    signals = _signals(INPUTS[model], 0.5)
    results = {}
    for version in (2, 3):
        path = build_fmu(model, fmi3_cache, fmi_version=version)
        results[version] = simulate_fmu(
            str(path), stop_time=0.5, input=signals, output_interval=0.01, solver="CVode", validate=True
        )
    assert results[2].dtype.names == results[3].dtype.names
    assert len(results[3]) == 51
    for name in results[2].dtype.names:
        assert np.array_equal(results[2][name], results[3][name]), name
    moving = "i_a" if model == "StepperMotor" else "theta_p"
    assert np.ptp(results[3][moving]) > 0.1  # the model did something: not a flat zero trace


def test_building_twice_gives_identical_fmi3_fmus_beside_the_fmi2_fmu(tmp_path):
    first = build_fmu("PanelMechanics", tmp_path / "a", fmi_version=3, force=True)
    second = build_fmu("PanelMechanics", tmp_path / "b", fmi_version=3, force=True)
    assert _sha256(first) == _sha256(second)
    fmi2 = build_fmu("PanelMechanics", tmp_path / "a")
    assert fmi2.parent != first.parent  # another build key: both live in one cache
    assert fmi2.is_file() and first.is_file() and fmu_guid(fmi2) != fmu_guid(first)


def test_variant_name_with_fmi3_suffix_is_the_model_built_as_fmi3(fmi3_cache):
    path = ensure_fmu("PanelMechanics-fmi3", fmus=fmi3_cache)
    assert path == build_fmu("PanelMechanics", fmi3_cache, fmi_version=3)
    assert read_model_description(str(path)).fmiVersion == "3.0"
    assert read_model_description(str(ensure_fmu("PanelMechanics", fmus=fmi3_cache))).fmiVersion == "2.0"


def test_cli_builds_fmi3_fmus_and_copies_them_beside_the_fmi2_ones(tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("HELIOSTEP_FMUS", str(tmp_path / "cache"))
    out = tmp_path / "fmus"
    assert main(["build-fmus", "--model", "PanelMechanicsSmallAngle", "--out", str(out)]) == 0
    assert main(["build-fmus", "--fmi", "3", "--model", "PanelMechanicsSmallAngle", "--out", str(out)]) == 0
    versions = {p.name: read_model_description(str(p)).fmiVersion for p in out.glob("*.fmu")}
    assert versions == {"PanelMechanicsSmallAngle.fmu": "2.0", "PanelMechanicsSmallAngle-fmi3.fmu": "3.0"}
    capsys.readouterr()
    with pytest.raises(SystemExit) as exit_info:
        main(["build-fmus", "--fmi", "4"])
    assert exit_info.value.code == 2
    assert "--fmi" in capsys.readouterr().err


@pytest.fixture
def motor(fmi3_cache, tmp_path):
    """An instantiated StepperMotor FMI 3.0 instance (fmpy's FMU3Model) and the messages it logs."""
    path = build_fmu("StepperMotor", fmi3_cache, fmi_version=3)
    description = read_model_description(str(path))
    unzipped = extract(str(path), unzipdir=str(tmp_path / "unzipped"))
    messages = []
    fmu = FMU3Model(
        guid=description.guid,
        unzipDirectory=unzipped,
        modelIdentifier=description.modelExchange.modelIdentifier,
        instanceName="motor",
    )
    fmu.instantiate(logMessage=lambda env, status, category, message: messages.append((status, message.decode())))
    vrs = {v.name: v.valueReference for v in description.modelVariables}
    yield fmu, vrs, messages
    fmu.freeInstance()
    fmu.freeLibrary()


def _refused(call, messages, expected):
    messages.clear()
    with pytest.raises(FMICallException) as refusal:
        call()
    assert refusal.value.status == FMI3_ERROR
    assert any(status == FMI3_ERROR and expected in text for status, text in messages), messages


def test_calls_out_of_the_state_machine_are_refused_and_change_nothing(motor):
    fmu, vrs, messages = motor
    _refused(lambda: fmu.getFloat64([vrs["v_a"]]), messages, "fmi3GetFloat64: not allowed in instantiated")
    _refused(fmu.enterContinuousTimeMode, messages, "fmi3EnterContinuousTimeMode: not allowed in instantiated")
    _refused(fmu.updateDiscreteStates, messages, "fmi3UpdateDiscreteStates: not allowed in instantiated")
    _refused(fmu.exitInitializationMode, messages, "not allowed in instantiated")
    # the refusals changed nothing: the instance still initializes and computes the model's values
    fmu.setFloat64([vrs["i_a_ref"]], [0.01])
    fmu.enterInitializationMode(startTime=0.25)
    _refused(fmu.enterContinuousTimeMode, messages, "not allowed in initialization mode")
    fmu.exitInitializationMode()
    assert fmu.updateDiscreteStates()[0] is False  # no discrete states: no further update needed
    fmu.enterContinuousTimeMode()
    _refused(fmu.updateDiscreteStates, messages, "not allowed in continuous-time mode")
    time, v_a, der_i_a = fmu.getFloat64([vrs["time"], vrs["v_a"], vrs["der(i_a)"]])
    # models/StepperMotor.mo at i_a = 0, omega = 0: v_a = K (i_a_ref - i_a) = 100 V/A * 0.01 A,
    # der(i_a) = v_a / L with L = 1.8 mH (below the 3.1 V limit)
    assert time == 0.25
    assert v_a == pytest.approx(1.0, rel=1e-12)
    assert der_i_a == pytest.approx(1.0 / 0.0018, rel=1e-12)
    derivatives = (fmi3Float64 * 2)()
    fmu.getContinuousStateDerivatives(derivatives, 2)
    assert derivatives[0] == der_i_a
    _refused(lambda: fmu.getContinuousStateDerivatives(derivatives, 3), messages, "nContinuousStates is 3")


def test_bad_arguments_are_refused_before_anything_is_written(motor):
    fmu, vrs, messages = motor
    _refused(lambda: fmu.setFloat64([vrs["tau"]], [1.0]), messages, "tau is computed by the model")
    # a refused value (FMI 3.0: the instance is in the error state now) allows only fmi3Reset & co.
    _refused(lambda: fmu.setFloat64([vrs["i_a_ref"]], [0.5]), messages, "not allowed in error")
    fmu.reset()
    _refused(lambda: fmu.setFloat64([vrs["time"]], [1.0]), messages, "time is the independent variable")
    fmu.reset()
    refs = (fmi3ValueReference * 2)(vrs["i_a_ref"], vrs["i_b_ref"])
    values = (fmi3Float64 * 1)(0.02)
    _refused(lambda: fmu.fmi3SetFloat64(fmu.component, refs, 2, values, 1), messages, "nValues is 1")
    fmu.enterInitializationMode()
    _refused(lambda: fmu.getFloat64([999]), messages, "invalid value reference 999")
    _refused(lambda: fmu.getInt32([0]), messages, "no variables of this type")
    fmu.reset()
    fmu.enterInitializationMode()
    fmu.exitInitializationMode()
    assert fmu.getFloat64([vrs["i_a_ref"], vrs["v_a"]]) == [0.0, 0.0]  # the rejected 0.02 never written
    fmu.terminate()
    _refused(fmu.enterEventMode, messages, "not allowed in terminated")


def test_wrong_instantiation_token_and_co_simulation_are_refused(fmi3_cache, tmp_path):
    path = build_fmu("PanelMechanics", fmi3_cache, fmi_version=3)
    description = read_model_description(str(path))
    unzipped = extract(str(path), unzipdir=str(tmp_path / "unzipped"))
    messages = []
    fmu = FMU3Model(
        guid="{00000000-0000-0000-0000-000000000000}",
        unzipDirectory=unzipped,
        modelIdentifier=description.modelExchange.modelIdentifier,
        instanceName="panel",
    )
    with pytest.raises(Exception, match="Failed to instantiate"):
        fmu.instantiate(logMessage=lambda env, status, category, message: messages.append(message.decode()))
    assert any("instantiation token does not match" in text for text in messages)
    fmu.freeLibrary()


def test_the_fmi3_fmu_rebuilt_from_its_build_description_simulates_the_same(fmi3_cache, tmp_path):
    """sources/buildDescription.xml lists what to compile (FMI 3.0, section 2.5.1.2): gcc on
    exactly those files, against fmpy's FMI 3.0 headers, gives a binary that simulates the same."""
    import subprocess
    import xml.etree.ElementTree as ET

    import fmpy

    path = build_fmu("PanelMechanics", fmi3_cache, fmi_version=3)
    unzipped = tmp_path / "unzipped"
    with zipfile.ZipFile(path) as archive:
        archive.extractall(unzipped)
    build = ET.parse(unzipped / "sources" / "buildDescription.xml").getroot()
    files = [str(unzipped / "sources" / f.get("name")) for f in build.iter("SourceFile")]
    assert [Path(f).name for f in files] == ["fmi3_model_exchange.c", "equations.c"]
    library = unzipped / "binaries" / "x86_64-linux" / "PanelMechanics.so"
    library.unlink()
    headers = Path(fmpy.__file__).parent / "c-code"
    subprocess.run(
        ["gcc", "-std=c99", "-O2", "-fPIC", "-shared", f"-I{headers}", f"-I{unzipped / 'sources'}", *files]
        + ["-o", str(library), "-lm"],
        check=True,
    )
    signals = _signals(INPUTS["PanelMechanics"], 0.2)
    rebuilt = simulate_fmu(str(unzipped), stop_time=0.2, input=signals, output_interval=0.01, solver="CVode")
    shipped = simulate_fmu(str(path), stop_time=0.2, input=signals, output_interval=0.01, solver="CVode")
    assert np.allclose(rebuilt["theta_p"], shipped["theta_p"], rtol=1e-12, atol=0)
    assert np.ptp(shipped["theta_p"]) > 0.01
