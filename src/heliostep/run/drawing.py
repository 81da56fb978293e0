"""A run's figures drawn: what they are drawn from (:class:`FigureJob`), the drawing on two cores
(:func:`draw_figures`) and the helper process that imports the plotting modules while the run
simulates (:func:`start_drawer`).

Importing the plotting modules (matplotlib, its 3-D toolkit that it imports itself, PIL) takes 0.2 s after
the command's own modules (``benchmarks/bench_plots.py``), a third of drawing a run's 8 figures one after the
other. A drawer forked before the simulation
(:class:`~heliostep.run.forked.Helper`) imports them meanwhile, on the other core; when the results are
written it is sent the :class:`FigureJob` and draws (forking once more for the second core), while
this process writes the records. The figures are the same PNGs, byte for byte, as drawn here
(``tests/run/test_forked.py``). A drawer that has ended before it is needed, or a job that does not pickle,
leaves the figures to be drawn as without one.
"""

from __future__ import annotations

import os
import shutil
import tempfile
from dataclasses import dataclass
from pathlib import Path

import pandas as pd

from heliostep.results.outputs import TMP_PREFIX
from heliostep.results.run_files import FIGURE_FILES, POWER_FILE
from heliostep.results.run_summary import RunMetadata
from heliostep.results.solution import SolutionPlotData
from heliostep.run.forked import Helper, in_parallel
from heliostep.scenario import Scenario

__all__ = ["CHILD_FIGURES", "OWN_FIGURES", "FigureJob", "draw_figure_names", "draw_figures", "start_drawer"]

#: The figures a forked child draws (with the power on the tube) while the drawing process draws
#: :data:`OWN_FIGURES`: about half the drawing each (seconds per figure, the paper's case, ``bench_plots.py``:
#: Figs. 8, 9 0.04; 14 0.05; 11, 12 0.07; 13 0.08; 10 0.12; the power on the tube 0.17 with its light computed
#: again, 0.82x that from a held run's kept light, ``RunResult.light_rows``).
CHILD_FIGURES = ("fig09_rotor_angle_ref.png", "fig13_panel_tracking.png", "fig14_torque_zoom.png")
OWN_FIGURES = tuple(name for name in FIGURE_FILES if name not in CHILD_FIGURES)


@dataclass(frozen=True)
class FigureJob:
    """Everything a run's figures are drawn from (a :class:`~heliostep.run.RunResult`'s parts; it pickles)."""

    source: pd.DataFrame | Path  # the trace, or its Parquet file (read by column)
    trace_metadata: dict[str, str]
    solution_plot: SolutionPlotData | None
    light: pd.DataFrame  # time, the panel angle reference and the panel angle: the power on the tube
    metadata: RunMetadata
    scenario: Scenario
    weather: object
    summary: dict
    light_rows: dict | None = None  # the figures' light at the rows of ``light`` (None: computed again)


def draw_figures(job: FigureJob, out_dir: Path) -> list[Path]:
    """The figures drawn into ``out_dir`` (each renamed into place there), on two cores: a forked
    child draws :data:`CHILD_FIGURES` and the power on the tube while this process draws the rest
    (:func:`~heliostep.run.forked.in_parallel`; one after the other where it cannot fork). The plotting
    modules are imported here (where the drawer has not imported them already), and the child
    inherits them: matplotlib is imported once, not once in each process."""
    from heliostep.plots.light import plot_light_run
    from heliostep.plots.run import plot_run

    staging = Path(tempfile.mkdtemp(prefix=TMP_PREFIX + "figures-", dir=out_dir))
    try:

        def figures(only: tuple[str, ...]) -> list[Path]:
            return plot_run(job.source, staging, job.trace_metadata, job.solution_plot, only=only)

        def child_share() -> list[Path]:
            drawn = figures(CHILD_FIGURES)
            return drawn + plot_light_run(
                job.light, job.metadata, job.scenario, staging, job.weather, job.summary, series=job.light_rows
            )

        theirs, ours = in_parallel(child_share, lambda: figures(OWN_FIGURES))
        order = [*FIGURE_FILES, POWER_FILE]
        drawn = sorted([*theirs, *ours], key=lambda path: order.index(Path(path).name))
        written = []
        for path in drawn:
            target = out_dir / Path(path).name
            os.replace(path, target)
            written.append(target)
        return written
    finally:
        shutil.rmtree(staging, ignore_errors=True)


def draw_figure_names(job: FigureJob, out_dir: Path) -> list[str]:
    """:func:`draw_figures`' file names (what the drawer sends back)."""
    return [path.name for path in draw_figures(job, out_dir)]


def _import_plotting() -> None:
    import heliostep.plots.light
    import heliostep.plots.run  # noqa: F401


def start_drawer() -> Helper | None:
    """A drawer (:class:`~heliostep.run.forked.Helper`) importing the plotting modules from now on,
    or None where no child is forked (:func:`~heliostep.run.forked.can_fork`)."""
    return Helper.start(_import_plotting)
