"""How :func:`~heliostep.run.run_scenario` runs a scenario: :class:`RunOptions`."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path

from heliostep.results.trace.files import ROW_GROUP_ROWS
from heliostep.run.supervision.supervisor import DEFAULT_WATCHDOG, StartMethod

__all__ = ["RunOptions"]


@dataclass(frozen=True)
class RunOptions:
    """How a scenario is run; the defaults are those of a run from Python (held trace, in this process).

    Attributes
    ----------
    progress : bool
        A progress bar over simulated time on a terminal.
    should_stop : callable, optional
        Asked between solver calls; when it returns True the run stops there and
        :class:`~heliostep.run.RunFailed` carries the trace so far (``reason == "interrupted"``).
    fmu_paths : mapping of str to Path, optional
        The scenario's FMUs already resolved (:func:`~heliostep.run.resolve_fmus`); resolved by the run when
        not given.
    keep_trace : bool
        False (a sweep's cases): no trace kept, the rows go to the figures as they come; nothing is written
        or plotted, and the figures are those with the trace kept, bit for bit (an interrupted run's not
        corrected at the cut).
    stream : bool, optional
        True: the trace streamed to a Parquet file while simulating; False: held in memory; None: streamed
        for windows longer than :data:`~heliostep.run.HELD_TRACE_MAX_DURATION`.
    trace_dir : str or Path, optional
        Where a streamed trace is written under a temporary name (the output folder, into which
        :meth:`~heliostep.run.RunResult.write` renames it); without one, a temporary folder removed with the
        result.
    row_group_rows : int
        Rows per row group of a streamed trace, and per chunk of the output rows' figures: held and streamed
        runs with the same value give the same figures bit for bit.
    supervise : bool
        Simulate in a supervised child process (:mod:`heliostep.run.supervision.supervisor`; ``heliostep run``'s
        default): an FMU that crashes, exits or hangs fails the run (``"fmu-crashed"``, ``"fmu-hung"``), named.
    watchdog : float  [s]
        With ``supervise``: an FMU with no FMI call begun for this long hangs.
    start_method : {"fork", "forkserver"}
        With ``supervise``: how the child starts; ``"forkserver"`` where this process runs threads (a Dask
        worker), since a fork copies one thread only.
    light_first_order : bool
        False (sweep cases): the light's first-order stepping terms left out (None), every other figure the
        same bit for bit.
    """

    progress: bool = False
    should_stop: Callable[[], bool] | None = None
    fmu_paths: Mapping[str, Path] | None = None
    keep_trace: bool = True
    stream: bool | None = None
    trace_dir: str | Path | None = None
    row_group_rows: int = ROW_GROUP_ROWS
    supervise: bool = False
    watchdog: float = DEFAULT_WATCHDOG
    start_method: StartMethod = "fork"
    light_first_order: bool = True
