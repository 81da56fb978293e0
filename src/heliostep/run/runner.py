"""``run_scenario``: a run set up, simulated once and summarized.

Its rows go in one pass to the run's figures and to its row sink (a closed loop's output rows once its
steps are decided, :mod:`heliostep.run.closed_loop`); a run that fails or is interrupted part-way still
returns (and writes) the trace so far, marked incomplete.
"""

from __future__ import annotations

import contextlib
import dataclasses
import functools
import os
import platform
import shutil
import sys
import tempfile
import time as clock
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from importlib import metadata as package_metadata
from pathlib import Path

import numpy as np

from heliostep._version import __version__
from heliostep.cosim import Connection, CoSimulation, FMUInfo, SimulationError, SolverOptions
from heliostep.drive.closed_loop import STEP_INDEX, TrackingLoop
from heliostep.drive.inputs import DriveInputs, prepare_inputs
from heliostep.errors import InputError
from heliostep.progress import bars_wanted
from heliostep.results.figures.run_figures import FigureStream, RunFigures, solution_recorder
from heliostep.results.figures.run_summary import RunMetadata, RunStatus
from heliostep.results.figures.solution import SolutionRecorder
from heliostep.results.light.on_tube import load_weather
from heliostep.results.output.files import TMP_PREFIX
from heliostep.results.trace.frame import UNITS, TraceAssembler, drive_metadata, figure_columns, trace_metadata
from heliostep.results.trace.sinks import HeldTrace, KeptRows, RowSink
from heliostep.results.trace.stream import TraceStream
from heliostep.run.bindings import parameters, present_roles, signals
from heliostep.run.closed_loop import decided_inputs, loop_inputs, sensor_parameters, tracking_loop
from heliostep.run.estimate import check_budget, estimate_run
from heliostep.run.fmus import communication_intervals, fmu_records, read_fmus, resolve_fmus
from heliostep.run.options import RunOptions
from heliostep.run.result import RunFailed, RunResult
from heliostep.run.supervision.allocator import restore_dynamic_heap
from heliostep.run.supervision.supervisor import simulate_supervised
from heliostep.scenario import Scenario, load_scenario
from heliostep.scenario.tracking import SENSOR_INSTANCE

__all__ = ["HELD_TRACE_MAX_DURATION", "SINK_ROWS", "VERSIONED_PACKAGES", "run_scenario", "run_versions"]

#: Packages whose versions go into a run's metadata.
VERSIONED_PACKAGES = ("fmpy", "pymoca", "casadi", "pvlib", "numpy", "scipy", "pandas")

#: Windows up to this long [s] keep their trace in memory (``RunResult.trace``, about 15,000 rows
#: per simulated hour on the paper's case at a 10 s grid, ~2.5 MB). Longer windows stream the trace
#: to Parquet row groups while simulating (:class:`~heliostep.results.trace.stream.TraceStream`)
#: and read it back from the file when asked, so the run's memory does not grow with the window.
HELD_TRACE_MAX_DURATION = 3600.0

#: The master's rows per block handed to the row sink (and the most it holds).
SINK_ROWS = 4096


@dataclass
class _PreparedRun:
    """A run checked and set up by :func:`run_scenario`, ready to simulate."""

    scenario: Scenario
    system: CoSimulation
    inputs: DriveInputs
    solver: SolverOptions
    roles: dict[str, str]
    meta: RunMetadata  # the run's metadata, completed by the simulation
    started: float  # [s] perf_counter at the start of run_scenario
    weather: object  # the weather file already read (None: clear sky)
    infos: dict[str, FMUInfo]
    values: dict  # the FMUs' parameters
    fmu_paths: dict[str, Path]
    loop: TrackingLoop | None = None  # a closed or hybrid loop's controller, deciding its steps

    @property
    def columns(self) -> list[str]:
        """The master's trace columns."""
        columns = ["time"] + [item.name for item in self.system.inputs]
        return columns + self._outputs

    @property
    def trace_columns(self) -> list[str]:
        """The master's columns the run's sink takes: a loop's phase currents first, as an open-loop run's,
        and not its step index (the assembler derives it from the steps decided)."""
        if self.loop is None:
            return self.columns
        names = [item.name for item in self.system.inputs if item.name != STEP_INDEX]
        currents = [name for name in ("i_a_ref", "i_b_ref") if name in names]
        return ["time", *currents, *[name for name in names if name not in currents], *self._outputs]

    @property
    def _outputs(self) -> list[str]:
        return [f"{name}.{output}" for name, info in self.system.fmus.items() for output in info.traced_outputs]


def run_scenario(
    scenario: Scenario | str | Path, options: RunOptions | None = None, *, overrides: Sequence[str] = ()
) -> RunResult:
    """Run a scenario.

    Parameters
    ----------
    scenario : Scenario, str or Path
        The scenario, or its YAML file (with ``overrides``, ``--set``-style ``KEY=VALUE`` strings).
    options : RunOptions, optional
        How to run it (:class:`~heliostep.run.options.RunOptions`; default: the trace held, in this process).

    Returns
    -------
    RunResult
        The trace (held, or streamed to a Parquet file for windows over :data:`HELD_TRACE_MAX_DURATION`),
        the figures (computed while simulating) and the metadata.

    Raises
    ------
    RunFailed
        The simulation failed or was interrupted part-way; it carries the incomplete
        :class:`~heliostep.run.result.RunResult` (the trace so far; a streamed trace file's metadata says
        how the run ended).
    InputError
        Bad input.
    """
    options = options if options is not None else RunOptions()
    if not isinstance(options, RunOptions):
        raise TypeError(f"options must be a RunOptions, not {type(options).__name__} (overrides go in overrides=)")
    if not isinstance(scenario, Scenario):
        scenario = load_scenario(scenario, tuple(overrides))
    prepared = _prepare(scenario, options.fmu_paths, clock.perf_counter(), options.should_stop, options.keep_trace)
    if prepared.loop is None:
        figures = _run_figures(prepared, options)
        sink, temporary = _row_sink(prepared, figures, options)
        with _discarded_on_error(sink, temporary):
            simulated = _co_simulate(prepared, figures.solution, sink, options)
    else:  # the output rows kept until the steps are decided, the solver steps' figures on them as they come
        recorder = solution_recorder(prepared.columns, prepared.inputs, prepared.roles)
        kept = KeptRows(prepared.columns)
        with _discarded_on_error(kept, None):
            simulated = _co_simulate(prepared, recorder, kept, options)
        prepared, figures = _on_decided_steps(prepared, recorder, kept, options)
        sink, temporary = _row_sink(prepared, figures, options)
        with _discarded_on_error(sink, temporary):
            kept.replay(sink, prepared.trace_columns, SINK_ROWS)
    with _discarded_on_error(sink, temporary):
        run = _summarize(prepared, figures, sink, temporary, simulated)
    if not run.complete:
        raise RunFailed(run.error or run.reason or "failed", run)
    return run


@contextlib.contextmanager
def _discarded_on_error(sink, temporary: Path | None):
    """No result (a bug, bad input found late, a forced stop): what ``sink`` kept goes, and ``temporary``."""
    try:
        yield
    except BaseException:
        sink.abort()
        if temporary is not None:
            shutil.rmtree(temporary, ignore_errors=True)
        raise


def _run_figures(prepared: _PreparedRun, options: RunOptions, solution: SolutionRecorder | None = None) -> RunFigures:
    """The run's one figure accumulator, fed while simulating (``solution``: its solver steps' recorder,
    if they are already recorded)."""
    return RunFigures.of_run(
        prepared.trace_columns,
        prepared.inputs,
        prepared.roles,
        figure_columns(prepared.roles),
        prepared.meta,
        prepared.scenario,
        prepared.weather,
        options.row_group_rows,
        light_first_order=options.light_first_order,
        solution=solution,
    )


def _prepare(
    scenario: Scenario,
    fmu_paths: Mapping[str, Path] | None,
    started: float,
    should_stop: Callable[[], bool] | None = None,
    keep_trace: bool = True,
) -> _PreparedRun:
    """The run checked and set up: its estimate against the budget, FMUs, roles, weather, drive
    inputs (:class:`~heliostep.drive.sequencer.PreparationStopped` on a stop request), the coupled system."""
    check_budget(scenario, estimate_run(scenario, HELD_TRACE_MAX_DURATION, keep_trace))  # before any work
    restore_dynamic_heap()  # in a Dask worker (its MALLOC_TRIM_THRESHOLD_): heliostep.run.supervision.allocator
    fmu_paths = dict(fmu_paths) if fmu_paths is not None else resolve_fmus(scenario)
    infos = read_fmus(scenario, fmu_paths)
    roles = present_roles(scenario, infos)
    try:  # a weather file that cannot be read, is for another site or misses the window: bad input, found now
        weather = load_weather(scenario)  # read once: the light figures take it from here
    except InputError as exc:
        raise InputError(f"{scenario.source}: optics.{exc}") from None
    inputs = prepare_inputs(scenario, should_stop)
    values = parameters(scenario, inputs, roles, infos)
    loop = None
    if scenario.tracking.mode != "open_loop":
        values[SENSOR_INSTANCE] = sensor_parameters(scenario)
        loop = tracking_loop(scenario, inputs, roles, weather)
    system = _system(scenario, infos, inputs, values, roles, loop)
    if loop is not None:
        inputs = loop_inputs(inputs, loop, scenario)
    solver = SolverOptions(
        rtol=scenario.solver.rtol,
        atol=scenario.solver.atol,
        max_step=scenario.solver.max_step or float("inf"),
        max_num_steps=scenario.solver.max_num_steps,
        loop_rtol=scenario.solver.loop_rtol,
        loop_atol=scenario.solver.loop_atol,
    )
    meta = _metadata(scenario, fmu_paths, infos, values, roles, inputs)
    return _PreparedRun(scenario, system, inputs, solver, roles, meta, started, weather, infos, values, fmu_paths, loop)


def _system(scenario: Scenario, infos, inputs: DriveInputs, values: dict, roles: dict, loop) -> CoSimulation:
    """The coupled system: connections (types, units, loops), parameter names and values, checked before
    simulating; a controller's inputs in place of the schedule's phase currents."""
    given = signals(inputs, roles, scenario.faults.stuck)
    if loop is not None:
        given = [item for item in given if item.name not in ("i_a_ref", "i_b_ref")]
    try:
        return CoSimulation(
            infos,
            [Connection(s, t, scenario.transformation(t)) for s, t in scenario.connection_pairs()],
            given,
            values,
            communication_intervals={name: h for name, (h, _) in communication_intervals(scenario, infos).items()},
            controller=loop,
        )
    except InputError as exc:
        raise InputError(f"{scenario.source}: {exc}") from None


def _on_decided_steps(
    prepared: _PreparedRun, recorder: SolutionRecorder, kept: KeptRows, options: RunOptions
) -> tuple[_PreparedRun, RunFigures]:
    """The run on the steps its controller decided (read from the rows kept): its inputs, metadata and
    figures, the solver steps' recorder told the steps it recorded on."""
    scenario = prepared.scenario
    inputs = decided_inputs(prepared.inputs, kept.frame(["time", STEP_INDEX]), scenario)
    meta = _metadata(scenario, prepared.fmu_paths, prepared.infos, prepared.values, prepared.roles, inputs)
    prepared = dataclasses.replace(prepared, inputs=inputs, meta=meta)
    recorder.steps_decided(inputs.schedule)
    return prepared, _run_figures(prepared, options, recorder)


def run_versions() -> dict:
    """heliostep's, Python's and :data:`VERSIONED_PACKAGES`' versions, as a run's metadata records them
    (the sizing sheet records the same)."""
    return {
        "heliostep": __version__,
        "python": platform.python_version(),
        "packages": {p: package_metadata.version(p) for p in VERSIONED_PACKAGES},
    }


def _metadata(
    scenario: Scenario,
    fmu_paths: Mapping[str, Path],
    infos: Mapping[str, FMUInfo],
    values: dict,
    roles: dict[str, str],
    inputs: DriveInputs,
) -> RunMetadata:
    """The run's metadata before simulating (the simulation adds its statistics and figures)."""
    units = dict(UNITS)
    for name, info in infos.items():
        units.update({f"{name}.{v}": info.variables[v].unit for v in info.outputs if info.variables[v].unit})
    meta = RunMetadata(
        **run_versions(),
        scenario=scenario.resolved_dict(),
        fmus=fmu_records(fmu_paths, infos),
        parameters=values,
        roles=roles,
        drive=drive_metadata(inputs),
        window_start=inputs.window_start.isoformat(),
        timezone=scenario.site.timezone,
        units=units,
    )
    intervals = communication_intervals(scenario, infos)  # the sampled components': each interval and its source
    if intervals:
        meta["communication_intervals"] = {n: {"interval_s": h, "from": came} for n, (h, came) in intervals.items()}
    return meta


def _row_sink(prepared: _PreparedRun, figures: RunFigures, options: RunOptions) -> tuple[RowSink, Path | None]:
    """Where the master's rows go (all feed ``figures``): not kept, held, or streamed to a file
    (with the temporary folder made for it, without ``options.trace_dir``)."""
    columns, assembler = prepared.trace_columns, TraceAssembler(prepared.inputs, prepared.roles)
    if not options.keep_trace:
        return FigureStream(columns, assembler, figures), None
    stream, trace_dir = options.stream, options.trace_dir
    if not (prepared.inputs.duration > HELD_TRACE_MAX_DURATION if stream is None else stream):
        return HeldTrace(columns, assembler, figures), None
    temporary = (
        None if trace_dir is not None else Path(tempfile.mkdtemp(prefix=f"heliostep-trace-{prepared.scenario.name}-"))
    )
    folder = Path(trace_dir) if trace_dir is not None else Path(temporary or ".")
    path = folder / f"{TMP_PREFIX}{os.getpid()}-{clock.time_ns():x}-trace.parquet"
    return TraceStream(path, columns, assembler, options.row_group_rows, figures), temporary


def _ended_status(result, duration: float) -> RunStatus:
    """Complete, unless an FMU asked to terminate before the window's end: the figures then cover only
    [0, t] of the window, so the run is incomplete (reason ``terminated``, the FMU and the time named)."""
    stop = result.termination_time
    if result.terminated and stop is not None and stop < duration * (1.0 - 1e-12):
        error = (
            f"{result.termination_reason} at t = {stop:.6g} s, before the window's end at {duration:.6g} s: "
            "the trace and the figures cover the window up to there only"
        )
        return RunStatus(False, error, "terminated", stop)
    return RunStatus(True)


def _co_simulate(prepared: _PreparedRun, monitor: SolutionRecorder | None, sink, options: RunOptions):
    """The co-simulation, its solver steps to ``monitor`` and its output rows to ``sink``: (status, the
    master's empty trace frame, its statistics); in a supervised child process with ``options.supervise``."""
    inputs = prepared.inputs
    bar = _progress_bar(inputs.duration) if options.progress else None
    simulate = prepared.system.simulate
    if options.supervise:
        simulate = functools.partial(
            simulate_supervised, prepared.system, watchdog=options.watchdog, start_method=options.start_method
        )
    try:
        result = simulate(
            0.0,
            inputs.duration,
            inputs.output_times,
            prepared.solver,
            progress=bar.update_to if bar else None,
            should_stop=options.should_stop,
            monitor=monitor,  # every solver step, for the figures
            sink=sink,
            sink_rows=SINK_ROWS,
        )  # the trace rows, in blocks
        return _ended_status(result, inputs.duration), result.trace, result.statistics
    except InputError as exc:  # found while setting up the FMUs, before any row (e.g. an unknown parameter)
        raise InputError(f"{prepared.scenario.source}: {exc}") from None
    except SimulationError as exc:
        reached = getattr(exc, "time", None)
        if reached is None or not np.isfinite(reached):
            reached = sink.last_time if sink.last_time is not None else 0.0
        return RunStatus(False, str(exc), getattr(exc, "reason", "failed"), reached), exc.trace, exc.statistics
    finally:
        if bar:
            bar.close()


def _summarize(
    prepared: _PreparedRun, figures: RunFigures, sink: RowSink, temporary: Path | None, simulated: tuple
) -> RunResult:
    """The co-simulation's outcome (``simulated``, :func:`_co_simulate`'s), the trace (held, or finished in its
    stream) and the figures, as a RunResult."""
    scenario, meta = prepared.scenario, prepared.meta
    status, raw, statistics = simulated
    status = sink.finish(status)  # the last rows kept (a streamed trace that cannot be written fails the run)
    meta["statistics"] = {
        **statistics,
        "run_wall_time": clock.perf_counter() - prepared.started,
        "peak_rss_mb_simulating": _peak_rss_mb(),
    }
    if statistics.get("terminated"):  # an FMU asked to stop: the run ends there (incomplete if before the end)
        meta["terminated"] = {
            "instances": list(statistics.get("termination_instances") or []),
            "time_s": statistics.get("termination_time"),
            "by": statistics.get("termination_reason"),
        }
    solution = figures.solution_figures()
    if solution and figures.solution is not None:  # every solver step's, so summarize(trace, meta) recomputes them
        if list(raw.columns) != figures.solution.columns:
            raise RuntimeError(
                f"solution recorder columns {figures.solution.columns} differ from the trace's {list(raw.columns)}"
            )
        meta["solution_figures"] = solution
    sink.close(
        trace_metadata(
            scenario.name, meta, sink.columns, status.complete, status.reason, status.time_reached, status.error
        )
    )  # a file's metadata says how the run ended
    summary = figures.summary(interrupted=status.reason == "interrupted" and sink.trace_kept)
    meta["statistics"]["figure_rows_held_max"] = figures.max_rows_held  # trace rows held at once for them
    meta["statistics"]["figure_step_rows_held_max"] = figures.output.max_step_rows
    return RunResult(
        scenario,
        sink.held_trace,
        summary,
        meta,
        status.complete,
        status.error,
        prepared.inputs,
        status.reason,
        status.time_reached,
        trace_file=sink.trace_file,
        temporary_folder=temporary,
        weather=prepared.weather,
        trace_kept=sink.trace_kept,
        solution_plot=figures.solution.plot_data() if figures.solution is not None else None,
        unwritten_trace=getattr(sink, "unwritten_trace", None),  # rows a full disk kept out of the stream
    )


def _peak_rss_mb() -> float | None:
    """The process's peak resident memory so far [MB] (None where the OS does not say): Linux's
    VmHWM, which is this program's own (``ru_maxrss`` keeps the parent's peak across fork and
    exec, so a process started by a big one would report that one's), else ``ru_maxrss``."""
    try:
        with open("/proc/self/status", encoding="ascii") as status:
            for line in status:
                if line.startswith("VmHWM:"):
                    return round(int(line.split()[1]) / 1024, 1)  # kB
    except OSError:
        pass
    try:
        import resource
    except ImportError:  # not on Windows
        return None
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return round(peak / (1024 * 1024 if sys.platform == "darwin" else 1024), 1)  # bytes on macOS, KiB on Linux


def _progress_bar(duration: float):
    """A tqdm bar over simulated time when on a terminal and not in CI (shown after 2 s); else None."""
    if not bars_wanted():
        return None
    from tqdm import tqdm

    class Bar(tqdm):
        def update_to(self, t: float) -> None:
            if t - self.n >= 0.01 * self.total or t >= self.total:
                self.update(t - self.n)

    return Bar(
        total=duration,
        unit="s",
        desc="simulating",
        mininterval=0.5,
        delay=2.0,
        bar_format="{l_bar}{bar}| {n:.1f}/{total:.1f} s simulated [{elapsed}<{remaining}]",
    )
