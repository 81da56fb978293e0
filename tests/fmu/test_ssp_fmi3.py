"""Issue #24: an FMI 3.0 component in an SSP 1.0 system, exported and read back. The paper's drive with
an FMI 2.0 ramp (the mini Gain) into the FMI 3.0 Lag3 (``tests/data/mini3cs/``, T = 0.25 s bound in the
SSP) is written by ``heliostep export-ssp``, checked by fmpy's validating SSD reader (the SSP 1.0 schemas:
FMI 3.0's Float64 and Int32 as SSP's Real and Integer), and read back by a scenario with
``system: system.ssp`` that runs the lag as a Co-Simulation FMU: the same run as the scenario itself,
and the lag's held output the recurrence of the sampled ramp (first principles)."""

from __future__ import annotations

import zipfile
from xml.etree import ElementTree

import numpy as np
import pytest

from heliostep.cli import main
from heliostep.paths import scenarios_dir
from heliostep.run import run_scenario
from heliostep.scenario import load_scenario
from third_party_fmu import build_mini_fmu
from third_party_fmu3cs import build_lag3_fmu

CENTRAL = scenarios_dir() / "jan21-central.yaml"
T_LAG, H = 0.25, 0.05
SSD = "http://ssp-standard.org/SSP1/SystemStructureDescription"


def test_an_ssp_with_an_fmi3_component_is_valid_and_read_back_gives_the_same_co_simulation(tmp_path):
    from fmpy.ssp.ssd import read_ssd

    gain, lag = build_mini_fmu("Gain", tmp_path / "vendor"), build_lag3_fmu(tmp_path / "vendor")
    system = (
        f"fmus.ramp={gain}",
        f"fmus.lag={lag}",
        "parameters.ramp={k: 0.0, b: 1.0}",
        f"parameters.lag={{T: {T_LAG}}}",
        "connections=[[motor.tau, mechanics.tau], [mechanics.theta, motor.theta], [mechanics.omega, motor.omega],"
        " [ramp.s, lag.u]]",
    )
    out = tmp_path / "system.ssp"
    assert main(["export-ssp", str(CENTRAL), "--out", str(out), *(x for o in system for x in ("--set", o))]) == 0
    ssd = read_ssd(str(out), validate=True)  # fmpy's reader, the SSP 1.0 schemas
    components = {element.name: element for element in ssd.system.elements}
    assert set(components) == {"motor", "mechanics", "ramp", "lag"}
    with zipfile.ZipFile(out) as archive:  # fmpy's Connector has no type: the SSD's own elements
        root = ElementTree.fromstring(archive.read("SystemStructure.ssd"))
    (element,) = [c for c in root.iter(f"{{{SSD}}}Component") if c.get("name") == "lag"]
    connectors = {c.get("name"): (c.get("kind"), c[0].tag.split("}")[1]) for c in element.iter(f"{{{SSD}}}Connector")}
    assert connectors == {
        "u": ("input", "Real"),
        "y": ("output", "Real"),
        "e": ("output", "Real"),
        "T": ("parameter", "Real"),
        "h_int": ("parameter", "Real"),
        "t_stop": ("parameter", "Real"),
        "misbehave": ("parameter", "Integer"),  # FMI 3.0's Int32
    }
    (binding,) = components["lag"].parameterBindings
    (parameter,) = binding.parameterValues[0].parameters
    assert (parameter.name, parameter.type, float(parameter.value)) == ("T", "Real", T_LAG)
    # read back: the system from the SSP, the lag run as Co-Simulation at 50 ms (the scenario's own key)
    scenario = out.with_name("from-ssp.yaml")
    scenario.write_text(
        CENTRAL.read_text().replace("fmus: {motor: StepperMotor, mechanics: PanelMechanics}\n", "system: system.ssp\n")
    )
    run = ("window.duration=3", f"communication_interval.lag={H}")
    read_back = load_scenario(scenario, run)
    assert read_back.parameters["lag"] == {"T": T_LAG} and ["ramp.s", "lag.u"] in map(
        list, read_back.connection_pairs()
    )
    original = run_scenario(CENTRAL, overrides=(*system, *run))
    again = run_scenario(read_back)
    assert again.metadata["statistics"]["sampled_components"]["lag"] == {"interval_s": H, "steps": 60}
    for key, value in original.summary.items():
        if key != "rows":
            assert again.summary[key] == value, key
    assert again.trace["lag.y"].to_numpy() == pytest.approx(original.trace["lag.y"].to_numpy(), abs=0, rel=0)
    # the held y at the points: y_(k+1) = t_k + (y_k - t_k) exp(-h / T), the ramp sampled, T from the SSP
    trace = again.trace
    at = trace[np.isclose(trace["time"] / H, np.round(trace["time"] / H), rtol=0, atol=1e-6)]
    after = at.drop_duplicates("time", keep="last")
    k = np.round(after["time"].to_numpy() / H).astype(int)
    y = np.zeros(61)
    for j in range(60):
        y[j + 1] = j * H + (y[j] - j * H) * np.exp(-H / T_LAG)
    assert len(after) == 61 and np.max(np.abs(after["lag.y"].to_numpy() - y[k])) < 1e-9
