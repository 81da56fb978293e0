"""heliostep.cosim.fast_events: an event's fixed work in one call of the compiled kernel (hs_event).

A change of mechanism, so the traces must be the Python path's bit for bit; where an FMU's
fmi2EventInfo asks for more (a next time event, terminateSimulation, changed nominals) the event
must go on in Python from that FMU, with the values the FMUs' own definitions give."""

import ctypes

import numpy as np
import pytest

import heliostep.cosim.fast_events as fast_events
import heliostep.cosim.integrator as integrator
from drive_system import DRIVE_CONNECTIONS, STEP_INDICES, STEP_TIMES, current_inputs
from heliostep.cosim.fmi import read_fmu
from heliostep.cosim.master import CoSimulation, PiecewiseConstant
from heliostep.drive.sequencer import Sequencer
from heliostep.run import run_scenario
from heliostep.scenario import load_scenario
from third_party_fmu import build_mini_fmu


@pytest.fixture(scope="module")
def mini(tmp_path_factory):
    out = tmp_path_factory.mktemp("mini")
    return {name: read_fmu(build_mini_fmu(name, out)) for name in ("Counter", "PassThrough", "Rescale")}


def _bits(trace):
    return {column: trace[column].to_numpy(dtype=float).view(np.uint64) for column in trace.columns}


def _same_bits(a, b):
    assert list(a.columns) == list(b.columns) and a.shape == b.shape
    for column, bits in _bits(a).items():
        assert np.array_equal(bits, _bits(b)[column]), column


def _drive_system(drive):
    return CoSimulation(drive, DRIVE_CONNECTIONS, current_inputs())


def _both_ways(monkeypatch, simulate):
    """``simulate()`` with the events in the kernel, then on the Python path (the general case's)."""
    fast = simulate()
    monkeypatch.setattr(fast_events, "fast_events", lambda *args: False)
    return fast, simulate()


def test_the_section_layout_matches_the_ctypes_mirror():
    for name, structure in fast_events.STRUCTURES.items():
        assert fast_events.describe(name) == ctypes.sizeof(structure), name
    for name, structure in fast_events.STRUCTURES.items():
        if name == "hs_event_info":  # fmpy's fmi2EventInfo: the C side names two of its fields
            described = fast_events.describe
            assert described("hs_event_info.next_event_time") == structure.nextEventTime.offset
            assert described("hs_event_info.next_event_time_defined") == structure.nextEventTimeDefined.offset
            continue
        for field, _ in structure._fields_:
            offset = fast_events.describe(f"{name}.{field}")
            if offset >= 0:  # hs_event_unit's first field is not listed (offset 0)
                assert offset == getattr(structure, field).offset, f"{name}.{field}"
    assert fast_events.describe("hs_event_args.info") == fast_events.EventArgs.info.offset
    for code in ("EVENT_DONE", "EVENT_GENERAL", "EVENT_CHANGED", "EVENT_FAILED", "EVENT_REINIT_FAILED"):
        assert fast_events.describe(code) == getattr(fast_events, code), code
    assert fast_events.describe("hs_events.no_such_field") == -1


@pytest.mark.parametrize("monitored", [False, True], ids=["normal mode", "one-step loop"])
def test_the_drive_steps_give_the_python_paths_trace_bit_for_bit(drive, monkeypatch, monitored):
    """Five input changes of the drive: every event wholly in the kernel, the trace the Python path's."""
    grid = np.arange(0.0, 0.5001, 0.01)

    def simulate():
        rows = []
        monitor = None
        if monitored:  # a monitor sees every row, the events' both sides included

            def monitor(block):
                rows.append(block.copy())

        result = _drive_system(drive).simulate(0.0, 0.5, grid, monitor=monitor)
        return result, rows

    (fast, fast_rows), (slow, slow_rows) = _both_ways(monkeypatch, simulate)
    _same_bits(fast.trace, slow.trace)
    assert fast.statistics["events"] == slow.statistics["events"] == 5
    assert fast.statistics["rhs"] == slow.statistics["rhs"]
    assert fast.statistics["compiled_events"] == 5 and fast.statistics["resumed_events"] == 0
    if monitored:  # the monitor sees the same rows, the kernel's events' rows among them
        assert np.array_equal(np.vstack(fast_rows), np.vstack(slow_rows))
    assert slow.statistics["compiled_events"] == 0
    # the step instants: the rows just before and after each step, the new currents on the second
    trace = fast.trace
    i_a, _ = Sequencer().reference_currents(STEP_INDICES)
    for t, current in zip(STEP_TIMES, i_a[1:]):
        rows = trace[trace["time"] == t]
        assert len(rows) == 2 and rows["i_a_ref"].iloc[1] == current


def test_a_scenario_run_gives_the_python_paths_trace_and_summary_bit_for_bit(monkeypatch):
    """The paper's five minutes (16 steps): the same trace and summary."""
    scenario = load_scenario("jan21-central")
    fast, slow = _both_ways(monkeypatch, lambda: run_scenario(scenario))
    _same_bits(fast.trace, slow.trace)
    assert fast.summary == slow.summary
    statistics = fast.metadata["statistics"]
    assert statistics["compiled_events"] == statistics["events"] == 16
    assert slow.metadata["statistics"]["compiled_events"] == 0


def test_the_python_callbacks_keep_the_python_events(drive, monkeypatch):
    monkeypatch.setattr(integrator, "compiled_kernel", lambda *args: None)
    result = _drive_system(drive).simulate(0.0, 0.5, np.arange(0.0, 0.5001, 0.05))
    assert result.statistics["compiled_rhs"] is False and result.statistics["compiled_events"] == 0


def test_time_events_and_terminate_go_on_in_python_from_the_fmu_that_asks(mini, monkeypatch):
    """Counter defines its next time event at every fmi2NewDiscreteStates (ticks every second) and asks to
    terminate at 9 s; beside it PassThrough integrates a master input (u_c: 1 until 2.5 s, then 3).
    Every event starts in the kernel and goes on in Python: the counts and the integral are the
    models' own (count = ticks = floor(t); integral of u_c), the end at 9 s, as on the Python path."""

    def simulate():
        system = CoSimulation(
            {"pt": mini["PassThrough"], "counter": mini["Counter"]},
            inputs=[PiecewiseConstant("u", "pt.u_c", np.array([2.5]), np.array([1.0, 3.0]))],
        )
        return system.simulate(0.0, 12.0, np.arange(0.0, 12.01, 0.5))

    fast, slow = _both_ways(monkeypatch, simulate)
    _same_bits(fast.trace, slow.trace)
    assert fast.terminated and slow.terminated and fast.termination_time == slow.termination_time == 9.0
    events = fast.statistics["events"]
    assert events == slow.statistics["events"] == 10  # 1, 2, 2.5, 3, ... 9 s (terminate asked in the last)
    assert fast.statistics["resumed_events"] == events and fast.statistics["compiled_events"] == 0
    trace = fast.trace
    for t in (1.5, 3.5, 8.5):
        row = trace[np.isclose(trace["time"], t, atol=1e-9)].iloc[-1]
        assert row["counter.count"] == np.floor(t)
        expected = t if t <= 2.5 else 2.5 + 3.0 * (t - 2.5)  # the integral of u_c
        assert row["pt.integral"] == pytest.approx(expected, rel=1e-5)


def test_changed_nominals_go_on_in_python_and_are_read_again(mini, monkeypatch):
    """Rescale: a time event every 0.25 s, its nominal changed at the one at t = 1 (the FMU counts the reads)."""

    def simulate():
        return CoSimulation({"r": mini["Rescale"]}).simulate(0.0, 3.0, np.arange(0.0, 3.01, 0.5))

    fast, slow = _both_ways(monkeypatch, simulate)
    _same_bits(fast.trace, slow.trace)
    assert fast.statistics["resumed_events"] == fast.statistics["events"] >= 11
    assert fast.statistics["nominal_reads"] == slow.statistics["nominal_reads"] == 2
    np.testing.assert_allclose(fast.trace["r.x"], np.exp(-fast.trace["time"]), rtol=1e-3)
