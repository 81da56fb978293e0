"""SSP 1.0 as other tools write it (tests/support/ssp_layouts.py: OMSimulator's layout): nested systems
flattened, parameter sets and mappings (.ssv, .ssm, inline, prefixed, through a system's parameter
connector) with the precedence SSP 1.0 gives them, units on connectors converted and checked, linear
transformations on connections applied by the master, parameter mapping tables; what is still refused
is named with the element, its name and the file."""

from __future__ import annotations

import json
import re
import zipfile

import numpy as np
import pytest
import yaml

from heliostep.cli import main
from heliostep.errors import InputError
from heliostep.paths import scenarios_dir
from heliostep.scenario import load_scenario
from ssp_layouts import (
    FLAT_CONNECTIONS,
    FLAT_INSTANCES,
    FLAT_PARAMETERS,
    HEAD,
    MOTOR_BINDING,
    SSV,
    connection,
    connector,
    nested_ssd,
    tracker_ssp,
    write_ssp,
)
from third_party_fmu import build_mini_fmu

CENTRAL = scenarios_dir() / "jan21-central.yaml"
SHORT = ["--set", "window.duration=60", "--no-plots"]


def _scenario(folder, name: str, **keys) -> str:
    """The paper's scenario with ``keys`` in place of its fmus, the roles on the flattened instances."""
    data = yaml.safe_load(CENTRAL.read_text())
    del data["fmus"]
    roles = load_scenario(CENTRAL).resolved_roles()
    data["roles"] = {
        role: target.replace("motor.", "drive_motor.").replace("mechanics.", "drive_load_mechanics.")
        for role, target in roles.items()
    }
    data.update(keys)
    path = folder / name
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return str(path)


@pytest.fixture(scope="module")
def tracker(tmp_path_factory, fmu_paths):
    folder = tmp_path_factory.mktemp("ssp-read")
    tracker_ssp(folder / "tracker.ssp", fmu_paths)
    flat = {
        "fmus": {"motor": None, "mechanics": None} | {n: str(fmu_paths[m]) for n, m in FLAT_INSTANCES.items()},
        "connections": [list(pair) for pair in FLAT_CONNECTIONS],
        "parameters": FLAT_PARAMETERS,
    }
    return folder, _scenario(folder, "nested.yaml", system="tracker.ssp"), _scenario(folder, "flat.yaml", **flat)


def test_a_nested_system_with_parameter_files_reads_as_its_flat_twin(tracker):
    _, nested, flat = tracker
    read, twin = load_scenario(nested), load_scenario(flat)
    assert set(read.fmus) == set(FLAT_INSTANCES)
    assert read.connection_pairs() == twin.connection_pairs() == FLAT_CONNECTIONS
    # the top system's .ssv through its .ssm: R from 1500 mOhm (over the motor's own 0.5: the higher level
    # wins), J_p doubled by the mapping; M_c by a prefixed binding on `drive`; T_c through `load`'s parameter
    # connector; T_d the motor's own; "drive.nothing.here" matches nothing and is ignored
    assert read.parameters == FLAT_PARAMETERS
    # N.m -> N.cm into `load`, N.cm -> N.m into the mechanics: the conversions compose to exactly (1, 0)
    assert read.transformations["drive_load_mechanics.tau"].model_dump() == {"factor": 1.0, "offset": 0.0}
    assert set(read.transformations) == {"drive_load_mechanics.tau"}


def test_heliostep_run_of_the_nested_ssp_gives_the_flat_runs_figures_bit_for_bit(tracker, monkeypatch):
    folder, nested, flat = tracker
    monkeypatch.chdir(folder)
    assert main(["run", nested, *SHORT, "--out", "nested"]) == 0
    assert main(["run", flat, *SHORT, "--out", "flat"]) == 0
    summaries = [json.loads((folder / out / "summary.json").read_text()) for out in ("nested", "flat")]
    assert summaries[0]["steps_commanded"] >= 3
    assert summaries[0] == summaries[1]
    traces = [(folder / out / "trace.csv").read_bytes() for out in ("nested", "flat")]
    assert traces[0] == traces[1]


def test_a_linear_transformation_on_a_connection_is_the_flat_scenarios_transformation(tracker, fmu_paths):
    folder, _, _ = tracker
    gear = '<ssc:LinearTransformation factor="1.25" offset="-0.003"/>'
    ssp = tracker_ssp(folder / "geared.ssp", fmu_paths, tau_transform=gear, load_tau_unit="N.m")
    read = load_scenario(_scenario(folder, "geared.yaml", system=ssp.name), ["window.duration=20"])
    assert read.transformation("drive_load_mechanics.tau") == (1.25, -0.003)
    flat = {
        "fmus": {"motor": None, "mechanics": None} | {n: str(fmu_paths[m]) for n, m in FLAT_INSTANCES.items()},
        "connections": [list(pair) for pair in FLAT_CONNECTIONS],
        "parameters": FLAT_PARAMETERS,
        "transformations": {"drive_load_mechanics.tau": {"factor": 1.25, "offset": -0.003}},
    }
    twin = load_scenario(_scenario(folder, "geared-flat.yaml", **flat), ["window.duration=20"])
    from heliostep.run import run_scenario

    runs = run_scenario(read), run_scenario(twin)
    assert runs[0].summary == runs[1].summary
    for column in runs[1].trace.columns:
        assert np.array_equal(runs[0].trace[column].to_numpy(), runs[1].trace[column].to_numpy()), column
    plain = run_scenario(
        load_scenario(_scenario(folder, "plain.yaml", **flat), ["window.duration=20", "transformations={}"])
    )
    assert not np.array_equal(runs[0].trace["drive_load_mechanics.theta"], plain.trace["drive_load_mechanics.theta"])


def test_the_master_applies_a_transformation_exactly_in_the_value_copy(tmp_path):
    """A ramp (the mini Gain, s = t) into a Gain's u through factor and offset: y = k u + b at every row,
    with u = factor * s + offset rounded as the master rounds it (no fused multiply-add)."""
    gain = build_mini_fmu("Gain", tmp_path)
    factor, offset, k, b = 1.7, -0.25, 3.0, 0.5
    from heliostep.cosim.fmi import read_fmu
    from heliostep.cosim.master import Connection, CoSimulation

    infos = {"ramp": read_fmu(gain), "gain": read_fmu(gain)}
    system = CoSimulation(
        infos,
        [Connection("ramp.s", "gain.u", (factor, offset))],
        parameters={"ramp": {"k": 0.0, "b": 1.0}, "gain": {"k": k, "b": b}},
    )
    trace = system.simulate(0.0, 2.0, output_times=np.linspace(0.0, 2.0, 41)).trace
    s, y = trace["ramp.s"].to_numpy(), trace["gain.y"].to_numpy()
    u = factor * s + offset
    assert np.array_equal(y, k * u + b)
    assert s[-1] == pytest.approx(2.0, rel=1e-6)


def _refused(folder, ssd: str, fmus, extra=None, name="bad.ssp") -> str:
    write_ssp(folder / name, ssd, fmus, extra)
    scenario = _scenario(folder, "bad.yaml", system=name)
    with pytest.raises(InputError) as caught:
        load_scenario(scenario)
    message = str(caught.value)
    assert message.startswith(f"{scenario}: system: {folder / name}: "), message
    return message


@pytest.mark.parametrize(
    ("change", "expected"),
    [
        (
            lambda ssd: ssd.replace(
                connection("load.theta", "motor.theta"),
                connection(
                    "load.theta",
                    "motor.theta",
                    '<ssc:IntegerMappingTransformation><ssc:MapEntry source="1" target="2"/>'
                    "</ssc:IntegerMappingTransformation>",
                ),
            ),
            r"ssd:Connection load\.theta -> motor\.theta in system 'drive' has an ssc:IntegerMappingTransformation",
        ),
        (
            lambda ssd: ssd.replace(
                'type="application/x-fmu-sharedlibrary" source="resources/PanelMechanics.fmu"',
                'type="application/x-ssp-package" source="resources/PanelMechanics.fmu"',
            ),
            r"ssd:Component 'mechanics' is of type 'application/x-ssp-package', not an FMU",
        ),
        (
            lambda ssd: ssd.replace(connector("tau", "output", "N.m"), connector("tau", "output", "N.cm")),
            r"ssd:Component 'motor': ssd:Connector 'tau' has unit 'N.cm', its FMU's variable 'N.m'",
        ),
        (
            lambda ssd: ssd.replace(connector("tau", "input", "N.cm"), connector("tau", "input", "rad")),
            r"ssd:Connection motor\.tau -> load\.tau in system 'drive': units 'N\.m' and 'rad' are of different",
        ),
        (
            lambda ssd: ssd.replace(
                '<ssd:ParameterBinding prefix="load.mechanics.">',
                '<ssd:ParameterBinding prefix="load.mechanics." sourceBase="component">',
            ),
            r"ssd:ParameterBinding of ssd:System 'drive': sourceBase=\"component\"",
        ),
        (
            lambda ssd: ssd.replace(
                '<ssv:Parameter name="M_c"><ssv:Real value="0.004"/>',
                '<ssv:Parameter name="M_c"><ssv:Binary value="00"/>',
            ),
            r"ssd:ParameterBinding of ssd:System 'drive': ssv:Parameter 'load\.mechanics\.M_c': Binary parameter",
        ),
        (
            lambda ssd: ssd.replace('source="resources/tracker.ssm"', 'source="resources/missing.ssm"'),
            r"ssd:ParameterMapping of ssd:System 'Root': its source 'resources/missing\.ssm' is not in the file",
        ),
    ],
)
def test_what_is_not_taken_is_refused_naming_the_element_and_the_file(tracker, fmu_paths, change, expected):
    folder, _, _ = tracker
    ssd = change(nested_ssd(motor_binding=MOTOR_BINDING))
    assert re.search(expected, _refused(folder, ssd, *_members(folder, fmu_paths)))


def _members(folder, fmu_paths) -> tuple[dict, dict]:
    """The tracker's FMUs (member -> file) and parameter files (member -> text)."""
    fmus = {f"resources/{name}.fmu": fmu_paths[name] for name in ("StepperMotor", "PanelMechanics")}
    with zipfile.ZipFile(folder / "tracker.ssp") as archive:
        return fmus, {m: archive.read(m).decode() for m in ("resources/tracker.ssv", "resources/tracker.ssm")}


def test_a_refused_ssp_is_exit_2_of_heliostep_run(tracker, fmu_paths, capsys):
    folder, _, _ = tracker
    ssd = nested_ssd().replace(
        '<ssd:Elements><ssd:Component name="motor"',
        '<ssd:Elements><ssd:SignalDictionaryReference name="bus" dictionary="signals"/><ssd:Component name="motor"',
    )
    write_ssp(folder / "bus.ssp", ssd, *_members(folder, fmu_paths))
    assert main(["run", _scenario(folder, "bus.yaml", system="bus.ssp"), *SHORT]) == 2
    assert "ssd:SignalDictionaryReference 'bus' is not supported" in capsys.readouterr().err


def test_parameter_mappings_take_integer_and_boolean_tables(tmp_path):
    counter = build_mini_fmu("Counter", tmp_path)
    component = '<ssd:Component name="counter" source="resources/counter.fmu">'
    mapping = (
        '<ssd:ParameterMapping><ssm:ParameterMapping version="1.0">'
        '<ssm:MappingEntry source="stride" target="step"><ssc:IntegerMappingTransformation>'
        '<ssc:MapEntry source="3" target="2"/></ssc:IntegerMappingTransformation></ssm:MappingEntry>'
        '<ssm:MappingEntry source="enabled" target="enabled"><ssc:BooleanMappingTransformation>'
        '<ssc:MapEntry source="true" target="false"/></ssc:BooleanMappingTransformation></ssm:MappingEntry>'
        "</ssm:ParameterMapping></ssd:ParameterMapping>"
    )
    ssd = (
        f'{HEAD}<ssd:System name="Root"><ssd:Elements>{component}<ssd:ParameterBindings><ssd:ParameterBinding>'
        f'<ssd:ParameterValues><ssv:ParameterSet {SSV} version="1.0" name="c"><ssv:Parameters>'
        '<ssv:Parameter name="stride"><ssv:Integer value="3"/></ssv:Parameter>'
        '<ssv:Parameter name="enabled"><ssv:Boolean value="true"/></ssv:Parameter>'
        '<ssv:Parameter name="period"><ssv:Integer value="2"/></ssv:Parameter>'
        f"</ssv:Parameters></ssv:ParameterSet></ssd:ParameterValues>{mapping}</ssd:ParameterBinding>"
        "</ssd:ParameterBindings></ssd:Component></ssd:Elements></ssd:System></ssd:SystemStructureDescription>"
    )
    write_ssp(tmp_path / "counter.ssp", ssd, {"resources/counter.fmu": counter})
    from heliostep.fmu.ssp import read_ssp

    system = read_ssp(tmp_path / "counter.ssp", tmp_path / "cache")
    assert system.parameters == {"counter": {"step": 2, "enabled": False, "period": 2}}
    assert system.connections == [] and set(system.fmus) == {"counter"}


def test_transformations_in_an_algebraic_loop_solved_on_the_python_path(tmp_path):
    """Two Gains in a loop, both connections transformed: the torn one read through its transformation by
    the loop solver, the other copied through it by the Python link (a transformed torn connection keeps
    the loop out of the compiled kernel); the closed form of u1 = f2 (k2 (f1 (k1 u1 + b1) + o1) + b2) + o2."""
    from heliostep.cosim.fmi import read_fmu
    from heliostep.cosim.master import Connection, CoSimulation

    gain = build_mini_fmu("Gain", tmp_path)
    (k1, b1), (k2, b2), (f1, o1), (f2, o2) = (0.5, 1.0), (0.4, -2.0), (1.5, 0.25), (-0.8, 3.0)
    system = CoSimulation(
        {"g1": read_fmu(gain), "g2": read_fmu(gain)},
        [Connection("g1.y", "g2.u", (f1, o1)), Connection("g2.y", "g1.u", (f2, o2))],
        parameters={"g1": {"k": k1, "b": b1}, "g2": {"k": k2, "b": b2}},
    )
    assert [c.target for c in system.torn] == ["g2.u"]
    trace = system.simulate(0.0, 1.0).trace
    u1 = (f2 * k2 * f1 * b1 + f2 * k2 * o1 + f2 * b2 + o2) / (1 - f2 * k2 * f1 * k1)
    y1 = k1 * u1 + b1
    y2 = k2 * (f1 * y1 + o1) + b2
    assert trace["g1.y"].to_numpy() == pytest.approx(y1, rel=1e-9)
    assert trace["g2.y"].to_numpy() == pytest.approx(y2, rel=1e-9)


def test_export_ssp_writes_a_transformation_that_reads_back(tmp_path):
    out = tmp_path / "geared.ssp"
    gear = "transformations={mechanics.tau: {factor: 1.25, offset: -0.003}}"
    assert main(["export-ssp", str(CENTRAL), "--out", str(out), "--set", gear]) == 0
    from fmpy.ssp.ssd import read_ssd

    read_ssd(str(out), validate=True)  # the SSP 1.0 schemas
    text = CENTRAL.read_text().replace(
        "fmus: {motor: StepperMotor, mechanics: PanelMechanics}\n", "system: geared.ssp\n"
    )
    (tmp_path / "s.yaml").write_text(text)
    read = load_scenario(tmp_path / "s.yaml")
    assert read.transformations == load_scenario(CENTRAL, [gear]).transformations
    assert read.connection_pairs() == load_scenario(CENTRAL).connection_pairs()
