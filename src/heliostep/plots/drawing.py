"""A run's figures drawn by one function: :func:`draw_run_figures` (the paper's Figs. 8-14, then the power on
the tube), one after the other, from a :class:`~heliostep.run.RunResult`."""

from __future__ import annotations

import os
import shutil
import tempfile
from collections.abc import Mapping
from pathlib import Path
from typing import Any, Protocol

import pandas as pd

from heliostep.plots.light import plot_light_run
from heliostep.plots.run import plot_run
from heliostep.results.figures.solution import SolutionPlotData
from heliostep.results.output.files import TMP_PREFIX

__all__ = ["DrawnRun", "draw_run_figures"]


class DrawnRun(Protocol):
    """What a run's figures are drawn from (:class:`heliostep.run.RunResult`)."""

    @property
    def held_trace(self) -> pd.DataFrame | None: ...

    @property
    def trace_file(self) -> Path | None: ...

    @property
    def solution_plot(self) -> SolutionPlotData | None: ...

    @property
    def metadata(self) -> Mapping: ...

    @property
    def scenario(self) -> Any: ...

    @property
    def weather(self) -> object: ...

    @property
    def summary(self) -> dict: ...

    def trace_metadata(self) -> dict[str, str]: ...

    def trace_columns(self, columns: list[str]) -> pd.DataFrame: ...


def draw_run_figures(result: DrawnRun, out_dir: str | Path) -> list[Path]:
    """Draw a run's figures into ``out_dir``: Figs. 8-14 (:func:`~heliostep.plots.run.plot_run`, a streamed
    trace read from its file by column) and the power on the tube (:func:`~heliostep.plots.light.plot_light_run`).

    The PNGs are drawn into a temporary folder inside ``out_dir`` and renamed into place once all are drawn,
    so ``out_dir`` never holds a half-written one.

    Parameters
    ----------
    result : RunResult
        The run, with its trace kept (held in memory or in its trace file).
    out_dir : str or Path
        Folder for the PNGs, created if missing.

    Returns
    -------
    list of Path
        The PNGs written, in figure order (a figure whose columns are missing is skipped).
    """
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    source = result.held_trace if result.held_trace is not None else result.trace_file
    if source is None:
        raise ValueError("the run kept no trace: no figure to draw")
    staging = Path(tempfile.mkdtemp(prefix=TMP_PREFIX + "figures-", dir=out_dir))
    try:
        drawn = plot_run(source, staging, result.trace_metadata(), result.solution_plot)
        panel = result.metadata.get("roles", {}).get("panel_angle", "")
        light = result.trace_columns(["panel_angle_ref", panel])
        drawn += plot_light_run(light, result.metadata, result.scenario, staging, result.weather, result.summary)
        written = []
        for path in drawn:
            target = out_dir / path.name
            os.replace(path, target)
            written.append(target)
        return written
    finally:
        shutil.rmtree(staging, ignore_errors=True)
