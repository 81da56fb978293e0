"""Issue #24: SSP 1.0 in and out. ``heliostep export-ssp`` writes the paper's scenario's system (FMUs,
connections, parameters) as an .ssp that fmpy's SSD reader accepts against the SSP 1.0 schemas it ships;
a scenario with ``system: system.ssp`` instead of its fmus reads it back and gives the same run."""

from __future__ import annotations

import zipfile

import pytest

from heliostep.cli import main
from heliostep.errors import InputError
from heliostep.paths import scenarios_dir
from heliostep.run import run_scenario
from heliostep.scenario import load_scenario

CENTRAL = scenarios_dir() / "jan21-central.yaml"
SHORT = ("window.duration=60", "parameters.motor.R=0.9")


@pytest.fixture(scope="module")
def exported(tmp_path_factory):
    folder = tmp_path_factory.mktemp("ssp")
    out = folder / "system.ssp"
    assert main(["export-ssp", str(CENTRAL), "--out", str(out), "--set", SHORT[1]]) == 0
    return out


def test_the_exported_ssp_is_valid_ssp_1_0_with_the_scenarios_system(exported):
    from fmpy.ssp.ssd import read_ssd

    ssd = read_ssd(str(exported), validate=True)  # fmpy's reader, the SSP 1.0 schemas
    components = {element.name: element for element in ssd.system.elements}
    assert set(components) == {"motor", "mechanics"}
    assert components["motor"].source == "resources/motor.fmu"
    links = [(c.startElement, c.startConnector, c.endElement, c.endConnector) for c in ssd.system.connections]
    assert links == [
        ("motor", "tau", "mechanics", "tau"),
        ("mechanics", "theta", "motor", "theta"),
        ("mechanics", "omega", "motor", "omega"),
    ]
    kinds = {c.name: c.kind for c in components["motor"].connectors}
    assert kinds["i_a_ref"] == "input" and kinds["tau"] == "output" and kinds["R"] == "parameter"
    (binding,) = components["motor"].parameterBindings
    (parameter,) = binding.parameterValues[0].parameters
    assert (parameter.name, parameter.type, float(parameter.value)) == ("R", "Real", 0.9)
    with zipfile.ZipFile(exported) as archive:
        assert {"resources/motor.fmu", "resources/mechanics.fmu"} <= set(archive.namelist())
    units = {unit.name for unit in ssd.units}
    assert {"A", "N.m", "rad"} <= units


def test_a_scenario_with_the_ssp_as_its_system_gives_the_same_run(exported):
    text = CENTRAL.read_text().replace(
        "fmus: {motor: StepperMotor, mechanics: PanelMechanics}\n", "system: system.ssp\n"
    )
    assert "system: system.ssp" in text and "fmus:" not in text
    scenario = exported.with_name("from-ssp.yaml")
    scenario.write_text(text)
    read_back = load_scenario(scenario, SHORT[:1])
    assert set(read_back.fmus) == {"motor", "mechanics"} and read_back.parameters == {"motor": {"R": 0.9}}
    assert read_back.connection_pairs() == load_scenario(CENTRAL).connection_pairs()
    original = run_scenario(CENTRAL, overrides=SHORT)
    again = run_scenario(read_back)
    assert original.summary["steps_commanded"] >= 3
    for key, value in original.summary.items():
        if key != "rows":
            assert again.summary[key] == value, key
    assert again.trace["motor.tau"].to_numpy() == pytest.approx(original.trace["motor.tau"].to_numpy(), abs=0, rel=0)


def test_an_ssp_that_is_not_one_is_an_input_error_naming_the_key_and_file(tmp_path):
    bad = tmp_path / "broken.ssp"
    bad.write_bytes(b"not a zip")
    (tmp_path / "s.yaml").write_text(CENTRAL.read_text() + "system: broken.ssp\n")
    with pytest.raises(InputError, match=r"s\.yaml: system: .*broken\.ssp: not a valid SSP 1\.0 file"):
        load_scenario(tmp_path / "s.yaml")
