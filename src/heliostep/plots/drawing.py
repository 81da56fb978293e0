"""A run's figures drawn by one function: :func:`draw_run_figures` (the paper's Figs. 8-14 and the power on
the tube) from a :class:`~heliostep.run.RunResult`, on two cores: a child forked once the run is done draws a
share of them while this process draws the rest (matplotlib's rendering is most of a short run's time)."""

from __future__ import annotations

import multiprocessing
import os
import shutil
import signal
import tempfile
import traceback
from collections.abc import Mapping
from pathlib import Path
from typing import Any, Protocol

import pandas as pd

from heliostep.errors import RunFailure
from heliostep.plots.light import POWER_FILE, plot_light_run
from heliostep.plots.run import FIGURE_FILES, plot_run
from heliostep.results.figures.solution import SolutionPlotData
from heliostep.results.output.files import TMP_PREFIX
from heliostep.results.output.folder import HELD_SIGNALS

__all__ = ["CHILD_SHARE", "DrawnRun", "draw_run_figures"]

#: The figures the forked child draws (with the power on the tube), about half the drawing's time.
CHILD_SHARE = (FIGURE_FILES[0], FIGURE_FILES[2])
#: Seconds the child may take before its share is drawn here instead (a child that hangs).
CHILD_LIMIT = 600.0
_ERROR = ".error"


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

    :data:`CHILD_SHARE` and the power on the tube are drawn by a child forked for it (where the OS forks; a
    child that hangs past :data:`CHILD_LIMIT` is killed and its share drawn here), the other figures here
    meanwhile. The PNGs are drawn into a temporary folder inside ``out_dir`` and renamed into place once all
    are drawn, so ``out_dir`` never holds a half-written one.

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
    child = None
    try:
        child = _start_child(result, source, staging)
        here = [name for name in FIGURE_FILES if name not in CHILD_SHARE]
        plot_run(source, staging, result.trace_metadata(), result.solution_plot, only=here)
        if child is None or not _joined(child, staging):
            _draw_child_share(result, source, staging)
        written = []
        for name in (*FIGURE_FILES, POWER_FILE):
            if (staging / name).exists():
                os.replace(staging / name, out_dir / name)
                written.append(out_dir / name)
        return written
    finally:
        if child is not None and child.is_alive():
            child.kill()
            child.join()
        shutil.rmtree(staging, ignore_errors=True)


def _draw_child_share(result: DrawnRun, source: pd.DataFrame | Path, staging: Path) -> None:
    plot_run(source, staging, result.trace_metadata(), result.solution_plot, only=CHILD_SHARE)
    panel = result.metadata.get("roles", {}).get("panel_angle", "")
    light = result.trace_columns(["panel_angle_ref", panel])
    plot_light_run(light, result.metadata, result.scenario, staging, result.weather, result.summary)


def _start_child(result: DrawnRun, source: pd.DataFrame | Path, staging: Path):
    """The child drawing :data:`CHILD_SHARE` and the power on the tube (None where the OS cannot fork)."""
    if "fork" not in multiprocessing.get_all_start_methods():
        return None
    child = multiprocessing.get_context("fork").Process(target=_child, args=(result, source, staging), daemon=True)
    child.start()
    return child


def _child(result: DrawnRun, source: pd.DataFrame | Path, staging: Path) -> None:
    """The child's work; a stop signal is the parent's to handle (it kills the child), an error is written
    for the parent to raise."""
    for sig in HELD_SIGNALS:
        signal.signal(sig, signal.SIG_IGN)
    try:
        _draw_child_share(result, source, staging)
    except BaseException:
        (staging / _ERROR).write_text(traceback.format_exc())
        os._exit(1)


def _joined(child, staging: Path) -> bool:
    """Whether the child drew its share (False: it hung, and was killed); its error raised here."""
    child.join(CHILD_LIMIT)
    if child.is_alive():
        child.kill()
        child.join()
        return False
    if (staging / _ERROR).exists():
        raise RunFailure("drawing the figures failed in the drawing process:\n" + (staging / _ERROR).read_text())
    if child.exitcode != 0:
        raise RunFailure(f"the drawing process ended with status {child.exitcode}")
    return True
