"""heliostep.results.figures.solution.SolutionRecorder, the one definition of a run's figures: the same figures bit
for bit whatever the blocks the solution rows come in (its sums over rows are running sums, one row after
the other), and when a supervised run's child hands its totals over to the supervisor's recorder block
after block (SolutionRecorder.totals, take_totals)."""

from __future__ import annotations

import dataclasses
import pickle
from pathlib import Path

import numpy as np
import pytest

import heliostep.results.figures.run_figures as run_figures
from heliostep.results.figures.solution import SolutionRecorder
from heliostep.run import run_scenario

SCENARIOS = Path(__file__).resolve().parents[2] / "scenarios"


@pytest.fixture(scope="module")
def slipping_run():
    """The weak motor's minute (it slips: missed steps), every solution row the recorder took kept."""
    kept, made = [], []

    class Keeping(SolutionRecorder):
        def __init__(self, *args, **kwargs):
            super().__init__(*args, **kwargs)
            made.append((args, kwargs))

        def __call__(self, rows):
            kept.append(np.array(rows, dtype=float, ndmin=2))
            super().__call__(rows)

    patch = pytest.MonkeyPatch()
    patch.setattr(run_figures, "SolutionRecorder", Keeping)
    try:
        run = run_scenario(SCENARIOS / "jan21-weak-motor.yaml", overrides=("window.duration=60",))
    finally:
        patch.undo()
    return run, np.vstack(kept), made[0]


def _plot_fields(recorder: SolutionRecorder) -> dict:
    return {field.name: getattr(recorder.plot_data(), field.name) for field in dataclasses.fields(recorder.plot_data())}


def _same_plot_data(a: dict, b: dict) -> None:
    for name, x in a.items():
        y = b[name]
        if isinstance(x, dict):
            assert x.keys() == y.keys(), name
            for key in x:
                assert np.array_equal(np.asarray(x[key]), np.asarray(y[key]), equal_nan=True), (name, key)
        elif isinstance(x, np.ndarray) or isinstance(y, np.ndarray):
            assert np.array_equal(x, y, equal_nan=True), name
        else:
            assert x == y, name


@pytest.mark.parametrize("block", [7, 1000, 65536])
def test_the_figures_do_not_depend_on_the_blocks_the_rows_come_in(slipping_run, block):
    run, rows, (args, kwargs) = slipping_run
    figures = run.metadata["solution_figures"]
    assert figures["solution_rows"] == len(rows) > 1000 and figures["missed_steps"] > 0  # it slips
    recorder = SolutionRecorder(*args, **{**kwargs, "block": block})
    rng = np.random.default_rng(block)
    cuts = np.sort(rng.choice(np.arange(1, len(rows)), size=200, replace=False))
    for part in np.split(rows, cuts):  # blocks of every size, single rows among them
        recorder(part)
    assert recorder.figures() == figures
    reference = SolutionRecorder(*args, **kwargs)
    reference(rows)
    _same_plot_data(_plot_fields(recorder), _plot_fields(reference))


def test_totals_handed_over_block_after_block_give_the_childs_figures(slipping_run):
    """The child's recorder sends its totals (pickled) after each block; the supervisor's takes them: its
    figures are the child's at every hand-over (a crash keeps the figures so far), and at the end."""
    run, rows, (args, kwargs) = slipping_run
    child, supervisor = SolutionRecorder(*args, **kwargs), SolutionRecorder(*args, **kwargs)
    for k, part in enumerate(np.array_split(rows, 37)):
        child(part)
        supervisor.take_totals(pickle.loads(pickle.dumps(child.totals())))
        if k in (5, 20):
            assert supervisor.figures() == child.figures()
    assert supervisor.figures() == child.figures() == run.metadata["solution_figures"]
    _same_plot_data(_plot_fields(supervisor), _plot_fields(child))
