"""A Co-Simulation-only FMU without a ``communication_interval`` runs at the step its DefaultExperiment suggests.

The mini Lag (``tests/data/mini/lag.c``) exported as a tool that offers Co-Simulation only would export it
(:func:`third_party_fmu.build_cs_only_mini_fmu`: no ModelExchange element), once with
``<DefaultExperiment stepSize="0.05"/>`` and once without. In the paper's drive with a ramp into the lag:
with the step, the run is the run with ``communication_interval.lag=0.05`` (the same trace, bit for bit)
and ``metadata.json`` says the interval and that it came from the FMU; a scenario's interval wins over
the FMU's; without a step anywhere the run is refused, exit 2, naming ``communication_interval``.
"""

from __future__ import annotations

import numpy as np
import pytest

from heliostep.cli import main
from heliostep.cosim import read_fmu
from heliostep.errors import InputError
from heliostep.paths import scenarios_dir
from heliostep.run import RunOptions, run_scenario
from heliostep.run.fmus import FROM_FMU, FROM_SCENARIO
from third_party_fmu import build_cs_only_mini_fmu, build_mini_fmu

CENTRAL = scenarios_dir() / "jan21-central.yaml"


@pytest.fixture(scope="module")
def fmus(tmp_path_factory):
    out = tmp_path_factory.mktemp("cs_only")
    return {
        "Gain": build_mini_fmu("Gain", out),
        "Lag": build_mini_fmu("Lag", out),
        "stepped": build_cs_only_mini_fmu("Lag", out / "stepped", 0.05),
        "bare": build_cs_only_mini_fmu("Lag", out / "bare", None),
    }


def overrides(fmus, lag: str, *more: str) -> tuple[str, ...]:
    return (
        "window.duration=4",
        f"fmus.ramp={fmus['Gain']}",
        f"fmus.lag={fmus[lag]}",
        "parameters.ramp={k: 0.0, b: 1.0}",
        "connections=[[motor.tau, mechanics.tau], [mechanics.theta, motor.theta], [mechanics.omega, motor.omega],"
        " [ramp.s, lag.u]]",
        *more,
    )


def test_read_as_the_fmu_offers(fmus):
    stepped = read_fmu(fmus["stepped"], co_simulation=None)
    assert stepped.co_simulation and stepped.default_step == 0.05
    assert not read_fmu(fmus["Lag"], co_simulation=None).co_simulation  # Model Exchange where offered
    assert read_fmu(fmus["Lag"], co_simulation=True).default_step is None
    with pytest.raises(InputError, match=r"Lag\.fmu: the FMU does not support Model Exchange .*communication_interval"):
        read_fmu(fmus["bare"], co_simulation=None)


def test_a_cs_only_fmu_runs_at_its_default_experiment_step_said_in_the_metadata(fmus):
    own = run_scenario(CENTRAL, RunOptions(supervise=False), overrides=overrides(fmus, "stepped"))
    given = run_scenario(
        CENTRAL, RunOptions(supervise=False), overrides=overrides(fmus, "Lag", "communication_interval.lag=0.05")
    )
    assert own.complete and given.complete
    assert own.metadata["communication_intervals"] == {"lag": {"interval_s": 0.05, "from": FROM_FMU}}
    assert given.metadata["communication_intervals"] == {"lag": {"interval_s": 0.05, "from": FROM_SCENARIO}}
    assert own.metadata["statistics"]["sampled_components"]["lag"] == {"interval_s": 0.05, "steps": 80}
    assert list(own.trace.columns) == list(given.trace.columns)
    assert np.array_equal(own.trace.to_numpy(), given.trace.to_numpy())  # the same run, bit for bit


def test_the_scenarios_interval_wins_over_the_fmus(fmus):
    run = run_scenario(
        CENTRAL, RunOptions(supervise=False), overrides=overrides(fmus, "stepped", "communication_interval.lag=0.1")
    )
    assert run.metadata["communication_intervals"] == {"lag": {"interval_s": 0.1, "from": FROM_SCENARIO}}
    assert run.metadata["statistics"]["sampled_components"]["lag"]["steps"] == 40


def test_a_cs_only_fmu_without_a_step_anywhere_is_exit_2_naming_the_key(fmus, tmp_path, capsys):
    args = ["run", str(CENTRAL), "--out", str(tmp_path / "out")]
    for item in overrides(fmus, "bare"):
        args += ["--set", item]
    assert main(args) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err and "fmus.lag" in err and "communication_interval" in err, err
