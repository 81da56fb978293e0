"""Issue #24: an FMI 2.0 Co-Simulation FMU that asks to terminate, as FMI 2.0 has a slave do it.

FMI 2.0 gives ``fmi2DoStep`` no termination flag: a slave that must stop returns ``fmi2Discard``,
then says ``fmi2Terminated`` through ``fmi2GetBooleanStatus`` and its ``fmi2LastSuccessfulTime``
through ``fmi2GetRealStatus`` (FMI 2.0.4, section 4.2.3). The mini ``LagStop``
(``tests/data/mini/lag_stop.c``: the Lag, T dy/dt = u - y, whose step stops at ``t_stop``) does so
in the example of ``test_sampled.py``: a ramp s = t into the lag, sampled every h = 0.1 s. With
t_stop = 1.25 s the step from 1.2 s ends at 1.25 s: the run terminates at the communication point
1.3 s, said in its statistics with the instance, the time and the last successful time, and the
lag's output is the first-principles value at 1.25 s (the ramp held at 1.2 over the half step).
A discard without ``fmi2Terminated`` is an FMU error naming the instance and the step.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import lag_reference
from heliostep.cosim import Connection, CoSimulation, SolverOptions, read_fmu
from heliostep.cosim.master import SimulationError
from third_party_fmu import build_mini_fmu

T_LAG, H, T_STOP, STOP = 0.5, 0.1, 1.25, 3.0


@pytest.fixture(scope="module")
def fmus(tmp_path_factory):
    out = tmp_path_factory.mktemp("discard")
    return {name: build_mini_fmu(name, out) for name in ("Gain", "LagStop")}


def example(fmus, says_terminated: int):
    system = CoSimulation(
        {"ramp": read_fmu(fmus["Gain"]), "lag": read_fmu(fmus["LagStop"], co_simulation=True)},
        [Connection("ramp.s", "lag.u")],
        parameters={
            "ramp": {"k": 0.0, "b": 1.0},
            "lag": {"T": T_LAG, "t_stop": T_STOP, "says_terminated": says_terminated},
        },
        communication_intervals={"lag": H},
    )
    return system.simulate(0.0, STOP, np.linspace(0.0, STOP, 301), SolverOptions(rtol=1e-9))


def test_a_cs_fmu_that_discards_and_says_terminated_ends_the_run_at_that_point_said_with_its_last_time(fmus):
    result = example(fmus, 1)
    statistics = result.statistics
    assert statistics["terminated"] and statistics["termination_instances"] == ["lag"]
    assert statistics["termination_time"] == pytest.approx(1.3)
    reason = statistics["termination_reason"]
    assert "lag asked to terminate the simulation (fmi2DoStep: fmi2Discard, then fmi2Terminated" in reason
    assert "its last successful time 1.25 s" in reason
    # first principles: the points k h up to 1.2 s from the recurrence, then half a step (to 1.25 s)
    # with the ramp held at 1.2
    points, y = lag_reference.sampled_lag(H, 1.2, T_LAG)
    assert points[-1] == pytest.approx(1.2)
    expected = 1.2 + (y[-1] - 1.2) * math.exp(-(T_STOP - 1.2) / T_LAG)
    trace = result.trace
    assert trace["time"].iloc[-1] == pytest.approx(1.3)
    assert trace["lag.y"].iloc[-1] == pytest.approx(expected, abs=1e-9)
    assert statistics["sampled_components"]["lag"]["steps"] == 13


def test_a_discarded_step_without_fmi2_terminated_is_an_fmu_error_naming_the_instance_and_the_step(fmus):
    with pytest.raises(SimulationError) as failed:
        example(fmus, 0)
    message = str(failed.value)
    assert "lag: fmi2DoStep returned fmi2Discard without fmi2Terminated (the step from t = 1.2 s to 1.3 s" in message
    assert "stopped at t = 1.25" in message  # the FMU's own message
    assert failed.value.trace["time"].iloc[-1] == pytest.approx(1.3)  # the rows so far kept
