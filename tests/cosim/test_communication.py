"""A system of Co-Simulation FMUs alone: the master runs its communication points, nothing to integrate.

The system: the mini Oscillator ``a`` (``tests/data/mini/oscillator.c``) alone, nothing pushing it (m = 1,
c = 100, d = 0.2, x0 = 0.1: the damped oscillation x(t) = e^(-z w t) (x0 cos(wd t) + z w x0 / wd sin(wd t)),
w = sqrt(c / m), z = d / (2 sqrt(c m)), wd = w sqrt(1 - z^2)), its x into the mini LagStop ``lag``
(``tests/data/mini/lag_stop.c``: T dy/dt = u - y, a step that stops at ``t_stop``), every H = 0.05 s, and the
lag's y into the mini Lag ``slow`` every 2 H. First principles: a's x at its points is the oscillation's; a
lag's y at its points is the recurrence of its input sampled after each point's steps and held, y_(k+1) =
u_k + (y_k - u_k) e^(-h/T), y_0 = 0; between points every output is held. A lag that stops at t_stop ends
the run at that point (fmi2Discard, then fmi2Terminated), or fails it without fmi2Terminated, the rows so far
kept; libcosim's numbers on another system: ``test_libcosim_oracle.py``.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from heliostep.cosim import Connection, CoSimulation, read_fmu
from heliostep.cosim.master import SimulationError
from third_party_fmu import build_mini_fmu

H, T_LAG, STOP = 0.05, 0.5, 2.0
OSCILLATOR = {"m": 1.0, "c": 100.0, "d": 0.2, "x0": 0.1}


@pytest.fixture(scope="module")
def fmus(tmp_path_factory):
    out = tmp_path_factory.mktemp("communication")
    return {name: build_mini_fmu(name, out) for name in ("Oscillator", "LagStop", "Lag")}


def system(fmus, t_stop: float = 1e300, says_terminated: int = 1) -> CoSimulation:
    return CoSimulation(
        {
            name: read_fmu(fmus[model], co_simulation=True)
            for name, model in (("a", "Oscillator"), ("lag", "LagStop"), ("slow", "Lag"))
        },
        [Connection("a.x", "lag.u"), Connection("lag.y", "slow.u")],
        parameters={
            "a": OSCILLATOR,
            "lag": {"T": T_LAG, "t_stop": t_stop, "says_terminated": says_terminated},
            "slow": {"T": T_LAG},
        },
        communication_intervals={"a": H, "lag": H, "slow": 2 * H},
    )


def oscillation(t: np.ndarray) -> np.ndarray:
    m, c, d, x0 = (OSCILLATOR[k] for k in ("m", "c", "d", "x0"))
    w, z = math.sqrt(c / m), d / (2.0 * math.sqrt(c * m))
    wd = w * math.sqrt(1.0 - z * z)
    return np.exp(-z * w * t) * (x0 * np.cos(wd * t) + z * w * x0 / wd * np.sin(wd * t))


def lag_of(u: np.ndarray, h: float) -> np.ndarray:
    """The lag's y at its points 0, h, 2 h, ... fed ``u`` (its input sampled at each point, held over the step)."""
    y = np.zeros(len(u))
    for k in range(len(u) - 1):
        y[k + 1] = u[k] + (y[k] - u[k]) * math.exp(-h / T_LAG)
    return y


def rows_after(trace, h: float):
    """The row after each point k h (the last row at its time) and k."""
    times = trace["time"].to_numpy()
    k = np.round(times / h)
    at = np.isclose(times, k * h, rtol=0, atol=1e-9) & np.r_[times[1:] != times[:-1], True]
    return trace[at], k[at].astype(int)


def test_each_component_steps_at_its_own_points_its_outputs_held_between_them(fmus):
    grid = np.linspace(0.0, STOP, 81)  # every 25 ms: half-way between points too
    result = system(fmus).simulate(0.0, STOP, grid)
    trace = result.trace
    after, k = rows_after(trace, H)
    assert np.array_equal(k, np.arange(round(STOP / H) + 1))
    assert np.max(np.abs(after["a.x"] - oscillation(k * H))) < 1e-7
    assert np.max(np.abs(after["lag.y"].to_numpy() - lag_of(after["a.x"].to_numpy(), H))) < 1e-9
    slow, j = rows_after(trace, 2 * H)
    assert np.max(np.abs(slow["slow.y"].to_numpy() - lag_of(slow["lag.y"].to_numpy(), 2 * H))) < 1e-9
    # half-way between points: the outputs of the row after the point before, held
    mid = trace[np.isclose((trace["time"] / H) % 1.0, 0.5, atol=1e-9)]
    before = after.set_index(k).loc[np.floor(mid["time"].to_numpy() / H + 1e-9).astype(int)]
    assert len(mid) == 40 and np.array_equal(mid.to_numpy()[:, 1:], before.to_numpy()[:, 1:])
    assert len(trace) == 1 + 2 * 40 + 40  # the start, both sides of each point, the output times between
    assert result.statistics["sampled_components"] == {
        "a": {"interval_s": H, "steps": 40},
        "lag": {"interval_s": H, "steps": 40},
        "slow": {"interval_s": 2 * H, "steps": 20},
    }


def test_a_component_that_asks_to_terminate_ends_the_run_at_that_point_with_its_outputs_there(fmus):
    result = system(fmus, t_stop=1.23).simulate(0.0, STOP, np.linspace(0.0, STOP, 81))
    assert result.terminated and result.termination_time == pytest.approx(1.25)
    assert result.statistics["termination_instances"] == ["lag"]
    assert (
        "lag asked to terminate the simulation (fmi2DoStep: fmi2Discard, then fmi2Terminated, its last "
        "successful time 1.23 s)" in result.termination_reason
    )
    trace = result.trace
    after, k = rows_after(trace, H)
    assert trace["time"].iloc[-1] == pytest.approx(1.25) and k[-1] == 25
    y = lag_of(after["a.x"].to_numpy(), H)  # to 1.2 s; then 30 ms (to t_stop) with a.x(1.2) held
    u = after["a.x"].iloc[-2]
    assert after["lag.y"].iloc[-1] == pytest.approx(u + (y[-2] - u) * math.exp(-0.03 / T_LAG), abs=1e-9)


def test_a_failed_step_fails_the_run_naming_it_the_rows_so_far_kept_to_the_row_before(fmus):
    with pytest.raises(SimulationError) as failed:
        system(fmus, t_stop=1.23, says_terminated=0).simulate(0.0, STOP, np.linspace(0.0, STOP, 81))
    assert "simulation failed at t = 1.25 s: lag: fmi2DoStep returned fmi2Discard without fmi2Terminated" in str(
        failed.value
    )
    trace = failed.value.trace
    assert trace["time"].iloc[-1] == pytest.approx(1.25) and trace["time"].iloc[-2] == pytest.approx(1.225)
    after, _ = rows_after(trace.iloc[:-1], H)
    assert trace["lag.y"].iloc[-1] == after["lag.y"].iloc[-1]  # the value of 1.2 s, held: the row before


def test_rows_handed_to_a_sink_are_the_trace_and_a_stop_asked_for_ends_it_there(fmus):
    held = system(fmus).simulate(0.0, 1.0, np.linspace(0.0, 1.0, 41)).trace
    blocks = []
    streamed = system(fmus).simulate(
        0.0, 1.0, np.linspace(0.0, 1.0, 41), sink=lambda rows: blocks.append(rows.copy()), sink_rows=7
    )
    assert len(streamed.trace) == 0 and max(len(b) for b in blocks) == 7
    assert np.array_equal(np.vstack(blocks), held.to_numpy())
    asked = []
    with pytest.raises(SimulationError) as stopped:
        system(fmus).simulate(
            0.0, 1.0, np.linspace(0.0, 1.0, 41), should_stop=lambda: len(asked) >= 5 or asked.append(1)
        )
    assert stopped.value.reason == "interrupted" and stopped.value.time == pytest.approx(0.15)
    assert np.array_equal(stopped.value.trace.to_numpy(), held.to_numpy()[: len(stopped.value.trace)])
    assert stopped.value.trace["time"].iloc[-1] == pytest.approx(0.15)


def test_the_last_point_is_at_the_stop_time_where_k_h_rounds_past_it(fmus):
    # 3 x 0.1 is 0.30000000000000004 in floating point: the components still step to the stop time, 0.3
    h, stop = 0.1, 0.3
    result = CoSimulation(
        {"a": read_fmu(fmus["Oscillator"], co_simulation=True)},
        [],
        parameters={"a": OSCILLATOR},
        communication_intervals={"a": h},
    ).simulate(0.0, stop, np.array([0.0, stop]))
    assert result.statistics["sampled_components"]["a"]["steps"] == 3
    last = result.trace.iloc[-1]
    assert last["time"] == stop and last["a.x"] == pytest.approx(oscillation(np.array([stop]))[0], abs=1e-7)
