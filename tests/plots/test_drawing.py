"""heliostep.plots.drawing: a run's figures drawn on two cores are the figures drawn in one process."""

from __future__ import annotations

import multiprocessing

import pytest

from heliostep.errors import RunFailure
from heliostep.paths import scenarios_dir
from heliostep.plots import drawing
from heliostep.plots.run import FIGURE_FILES
from heliostep.results.output.run_files import POWER_FILE
from heliostep.run import run_scenario


@pytest.fixture(scope="module")
def result(fmu_paths):
    return run_scenario(scenarios_dir() / "jan21-central.yaml", overrides=("window.duration=20",))


def test_the_forked_childs_share_and_this_processs_make_the_figures_of_one_process(result, tmp_path, monkeypatch):
    both = drawing.draw_run_figures(result, tmp_path / "both")
    assert [path.name for path in both] == [*FIGURE_FILES[:-1], POWER_FILE]  # (no tracking loop in open loop)
    monkeypatch.setattr(multiprocessing, "get_all_start_methods", lambda: ["spawn"])  # no fork: all drawn here
    alone = drawing.draw_run_figures(result, tmp_path / "alone")
    assert [path.name for path in alone] == [path.name for path in both]
    for drawn, reference in zip(both, alone):
        assert drawn.read_bytes() == reference.read_bytes(), drawn.name
    assert not list((tmp_path / "both").glob(".heliostep-tmp-*"))


def test_an_error_in_the_drawing_child_is_raised_with_its_traceback(result, tmp_path, monkeypatch):
    def broken(*args, **kwargs):
        raise ValueError("a figure that cannot be drawn")

    monkeypatch.setattr(drawing, "plot_light_run", broken)  # drawn by the child (the power on the tube)
    with pytest.raises(RunFailure, match="(?s)drawing process.*ValueError: a figure that cannot be drawn"):
        drawing.draw_run_figures(result, tmp_path / "out")
    assert not list((tmp_path / "out").iterdir())  # nothing half-drawn left
