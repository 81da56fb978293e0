"""One pass: a run's summary, computed while it simulates (no trace read back), equals the summary
that the trace gives read back after the run (the solution's figures merged with the output rows'
by precedence, and at a cut recomputed from the rows up to the step in progress), for held and
streamed runs (odd row groups and master blocks), interrupted and failed runs."""

from __future__ import annotations

import pytest

from figures_oracle import summary_at_cut_before, trace_summary_before
from heliostep.paths import scenarios_dir
from heliostep.run import RunFailed, RunOptions, run_scenario

SCENARIOS = scenarios_dir()
WINDOW = ["window.duration=20"]
#: Long enough for steps judged before the cut (the weak motor steps at about 9, 28 and 47 s).
WINDOWS = {"jan21-central.yaml": WINDOW, "jan21-weak-motor.yaml": ["window.duration=45"]}


def _assert_summary_is_the_traces(run) -> None:
    expected = trace_summary_before(run.trace, run.metadata)
    if run.reason == "interrupted":
        expected = summary_at_cut_before(run.trace, run.metadata, expected)
    summary = run.summary
    for key, value in expected.items():
        assert key in summary and summary[key] == value, key
    assert [k for k in summary if k in expected] == list(expected)  # the same order in summary.json


@pytest.mark.parametrize("scenario", ["jan21-central.yaml", "jan21-weak-motor.yaml"])
@pytest.mark.parametrize("stream", [False, True])
@pytest.mark.parametrize("fraction", [0.15, 0.4, 0.6, 0.85, 0.97])
def test_interrupted_summary_is_that_of_the_trace_so_far(fmu_paths, tmp_path, monkeypatch, scenario, stream, fraction):
    import heliostep.run.runner as runner

    monkeypatch.setattr(runner, "SINK_ROWS", 5)
    asked = []
    run_scenario(
        SCENARIOS / scenario, RunOptions(should_stop=lambda: asked.append(1) and False), overrides=WINDOWS[scenario]
    )
    stops_after = int(fraction * len(asked))  # stopped part-way: at a step, while settling, idle
    calls = []

    def should_stop():
        calls.append(1)
        return len(calls) > stops_after

    with pytest.raises(RunFailed) as failed:
        run_scenario(
            SCENARIOS / scenario,
            RunOptions(
                stream=stream, trace_dir=tmp_path if stream else None, row_group_rows=23, should_stop=should_stop
            ),
            overrides=WINDOWS[scenario],
        )
    run = failed.value.result
    assert run.reason == "interrupted" and run.trace_rows > 0
    _assert_summary_is_the_traces(run)


def test_failed_run_summary_is_that_of_the_trace_so_far(fmu_paths):
    with pytest.raises(RunFailed) as failed:
        run_scenario(SCENARIOS / "jan21-central.yaml", overrides=["solver.max_num_steps=40"])
    run = failed.value.result
    assert run.reason == "failed"
    # the solution went on past the last output row: the steps lost are the output rows'
    assert run.metadata["solution_figures"]["end_time_s"] > run.trace["time"].iloc[-1]
    _assert_summary_is_the_traces(run)


@pytest.mark.parametrize("stream", [False, True])
def test_complete_run_summary_is_that_of_the_trace(fmu_paths, tmp_path, stream):
    run = run_scenario(
        SCENARIOS / "jan21-weak-motor.yaml",
        RunOptions(stream=stream, trace_dir=tmp_path, row_group_rows=23),
        overrides=WINDOW,
    )
    _assert_summary_is_the_traces(run)
