"""``run_scenario``: heliostep's one public entry point (re-exported as ``heliostep.run_scenario``).

scenario → drive inputs (:mod:`heliostep.drive`) → master (:mod:`heliostep.cosim`) → trace, figures
from every solver step and light on the tube (:mod:`heliostep.results`) → plots
(:mod:`heliostep.plots`, on request). The FMU variables each part of the drive uses are found
through the scenario's roles, resolved here once. A run that fails or is interrupted part-way
still returns (and writes) the trace so far, marked incomplete. The command line is
:mod:`heliostep.cli.run`.
"""

from __future__ import annotations

import hashlib
import json
import os
import platform
import shutil
import sys
import tempfile
import time as clock
import weakref
from collections.abc import Callable
from dataclasses import dataclass, field
from importlib import metadata as package_metadata
from pathlib import Path

import numpy as np
import pandas as pd

from heliostep._version import __version__
from heliostep.cosim import (
    Connection,
    CoSimulation,
    FMUInfo,
    PiecewiseConstant,
    SimulationError,
    SolverOptions,
    read_fmu,
)
from heliostep.drive.inputs import DriveInputs, prepare_inputs
from heliostep.drive.sequencer import idle_currents
from heliostep.errors import HeliostepError, InputError
from heliostep.fmu.build import ensure_fmu
from heliostep.results.light import load_weather
from heliostep.results.outputs import (
    TMP_PREFIX,
    atomic_path,
    remove_stale,
    write_text_atomic,
)
from heliostep.results.run_figures import FigureStream, present_columns, run_figures, summary_at_cut
from heliostep.results.summary import SolutionRecorder
from heliostep.results.trace import UNITS, TraceAssembler, drive_metadata, figure_columns, trace_metadata
from heliostep.results.trace_io import ROW_GROUP_ROWS, TraceWriteError, copy_trace_to_csv, read_trace, write_trace
from heliostep.results.trace_stream import TraceStream
from heliostep.scenario import (
    INPUT_ROLES,
    OUTPUT_ROLES,
    PARAMETER_ROLES,
    Scenario,
    load_scenario,
)

#: Packages whose versions go into a run's metadata.
VERSIONED_PACKAGES = ("fmpy", "pymoca", "casadi", "pvlib", "numpy", "scipy", "pandas")

#: Windows up to this long [s] keep their trace in memory (``RunResult.trace``, about 15,000 rows
#: per simulated hour on the paper's case at a 10 s grid, ~2.5 MB). Longer windows stream the trace
#: to Parquet row groups while simulating (:class:`~heliostep.results.trace_stream.TraceStream`)
#: and read it back from the file when asked, so the run's memory does not grow with the window.
HELD_TRACE_MAX_DURATION = 3600.0

#: The master's rows per block handed to the trace stream (and the most it holds).
SINK_ROWS = 4096


@dataclass
class RunResult:
    """The outcome of :func:`run_scenario`.

    ``complete`` is False when the simulation failed or was interrupted part-way; ``error`` then
    says why, ``reason`` is ``"failed"`` or ``"interrupted"``, ``time_reached`` the simulated time
    reached [s], and ``trace`` holds the rows computed until then.

    ``trace`` is the trace in memory (``held_trace``) for windows up to
    :data:`HELD_TRACE_MAX_DURATION`; for longer windows it was streamed to ``trace_file`` (a
    Parquet trace) while simulating and each access reads it from there (use
    :meth:`trace_columns` for only some columns). After :meth:`write` ``trace_file`` is the
    output folder's ``trace.parquet``; a file in a temporary folder of the run's own is removed
    with the result.

    The summary of an interrupted run does not judge the step in progress at the cut: when the
    last step before the cut looks missed or unsettled there, the step figures (steps commanded,
    executed, missed, lost, settling) are those up to that step, and ``step_in_progress_at_cut_s``
    gives its time.
    """

    scenario: Scenario
    held_trace: pd.DataFrame | None
    summary: dict
    metadata: dict
    complete: bool = True
    error: str | None = None
    inputs: DriveInputs | None = field(default=None, repr=False)
    reason: str | None = None
    time_reached: float | None = None
    trace_file: Path | None = None
    temporary_folder: Path | None = field(default=None, repr=False)
    weather: object = field(default=None, repr=False)  # the weather file read once (None: clear sky)
    trace_kept: bool = True  # False: run_scenario(..., keep_trace=False), figures only

    def __post_init__(self) -> None:
        if not self.trace_kept:
            if self.held_trace is not None or self.trace_file is not None:
                raise ValueError("a RunResult without trace (trace_kept=False) has no held trace nor trace file")
            return
        if self.held_trace is None and self.trace_file is None:
            raise ValueError("a RunResult needs its trace in memory or in a trace file")
        if self.temporary_folder is not None:  # the run's own folder goes with the result
            weakref.finalize(self, shutil.rmtree, str(self.temporary_folder), True)
        if self.reason == "interrupted" and self.summary:
            source = self.held_trace if self.held_trace is not None else self.trace_file
            self.summary = summary_at_cut(source, figure_columns(self.metadata.get("roles", {})), self.metadata,
                                          self.summary)

    def _require_trace(self) -> None:
        if not self.trace_kept:
            raise HeliostepError(f"{self.scenario.name}: this run kept no trace (run_scenario(..., keep_trace=False)): "
                                 "only its summary and metadata")

    @property
    def trace(self) -> pd.DataFrame:
        """The trace: held in memory, or read from :attr:`trace_file` at each access."""
        self._require_trace()
        if self.held_trace is not None:
            return self.held_trace
        return read_trace(self.trace_file)[0]

    @property
    def trace_column_names(self) -> list[str]:
        self._require_trace()
        if self.held_trace is not None:
            return list(self.held_trace.columns)
        import pyarrow.parquet as pq

        return list(pq.read_schema(self.trace_file).names)

    @property
    def trace_rows(self) -> int:
        """The trace's number of rows (a file's from its footer, no row read)."""
        self._require_trace()
        if self.held_trace is not None:
            return len(self.held_trace)
        import pyarrow.parquet as pq

        return pq.ParquetFile(self.trace_file).metadata.num_rows

    def trace_columns(self, columns: list[str]) -> pd.DataFrame:
        """``time`` and those of ``columns`` the trace has, as a frame (read from the file when
        streamed: the other columns are never loaded)."""
        self._require_trace()
        wanted = present_columns(self.held_trace if self.held_trace is not None else self.trace_file, columns)
        if self.held_trace is not None:
            return self.held_trace[wanted]
        return read_trace(self.trace_file, wanted)[0]

    def to_pandas(self) -> pd.DataFrame:
        """The trace as a DataFrame (a copy)."""
        return self.trace.copy()

    def plot(self, out_dir: str | Path) -> list[Path]:
        """Write the paper's Figs. 8–14 and the power on the tube for this run into ``out_dir``
        (each file renamed into place)."""
        self._require_trace()
        from heliostep.plots.light import plot_light_run
        from heliostep.plots.run import plot_run

        out_dir = Path(out_dir)
        out_dir.mkdir(parents=True, exist_ok=True)
        staging = Path(tempfile.mkdtemp(prefix=TMP_PREFIX + "figures-", dir=out_dir))
        try:
            source = self.held_trace if self.held_trace is not None else self.trace_file  # a file: read by column
            drawn = plot_run(source, staging, self.trace_metadata())
            light = self.trace_columns(["panel_angle_ref", self.metadata.get("roles", {}).get("panel_angle", "")])
            drawn += plot_light_run(light, self.metadata, self.scenario, staging, self.weather)  # power on the tube
            written = []
            for path in drawn:
                target = out_dir / Path(path).name
                os.replace(path, target)
                written.append(target)
            return written
        finally:
            shutil.rmtree(staging, ignore_errors=True)

    def trace_metadata(self) -> dict[str, str]:
        return trace_metadata(self.scenario.name, self.metadata, self.trace_column_names, self.complete,
                              self.reason, self.time_reached, self.error)

    def summary_record(self) -> dict:
        """What ``summary.json`` holds: completeness (and why not), then the figures."""
        head = {"complete": self.complete, "error": self.error}
        if not self.complete:
            head["reason"] = self.reason or "failed"
            head["time_reached_s"] = self.time_reached
        return {**head, **self.summary}

    def write(self, out_dir: str | Path, plots: bool = True, csv: bool = True,
              should_stop: Callable[[], bool] | None = None) -> dict[str, Path]:
        """Write trace (Parquet, and CSV unless ``csv=False``), summary.json, metadata.json and
        plots into ``out_dir`` (a run that kept no trace: summary.json and metadata.json). The
        trace's metadata, summary.json and metadata.json all say ``complete`` (and, when not,
        ``reason`` and the time reached).

        Every file is written under a temporary name in ``out_dir`` and renamed into place, so no
        file is ever cut short under its final name. Files of heliostep's own kinds left by an
        earlier run and not written now are removed. When ``should_stop()`` turns true the
        figures (drawn last) are skipped.
        """
        out_dir = Path(out_dir)
        out_dir.mkdir(parents=True, exist_ok=True)
        written = {}
        if not self.trace_kept:  # figures only: summary.json and metadata.json
            plots = False
        elif self.held_trace is not None:
            for suffix in ("parquet", "csv") if csv else ("parquet",):
                path = out_dir / f"trace.{suffix}"
                with atomic_path(path) as tmp:
                    write_trace(self.held_trace, tmp, self.trace_metadata())
                written[path.name] = path
        else:  # streamed: the finished file is renamed (or copied) into place, the CSV made from it
            written["trace.parquet"] = self._place_trace_file(out_dir / "trace.parquet")
            if csv:
                with atomic_path(out_dir / "trace.csv") as tmp:
                    copy_trace_to_csv(self.trace_file, tmp, self.trace_metadata())
                written["trace.csv"] = out_dir / "trace.csv"
        status = {k: v for k, v in self.summary_record().items() if k in ("complete", "error", "reason", "time_reached_s")}
        for name, content in (("metadata.json", {**status, **self.metadata}), ("summary.json", self.summary_record())):
            written[name] = write_text_atomic(out_dir / name, json.dumps(content, indent=2, default=str) + "\n")
        if plots and self.trace_rows and not (should_stop and should_stop()):
            for path in self.plot(out_dir):
                written[path.name] = path
        remove_stale(out_dir, written.values())
        return written


    def _place_trace_file(self, target: Path) -> Path:
        """The streamed trace as ``target``: renamed when it is a temporary file of the same
        folder, else copied (under a temporary name, then renamed)."""
        source = Path(self.trace_file)
        if source == target:
            return target
        if source.parent == target.parent and source.name.startswith(TMP_PREFIX):
            os.replace(source, target)
        else:
            with atomic_path(target) as tmp:
                shutil.copyfile(source, tmp)
        if self.temporary_folder is None or source.parent == target.parent:
            self.trace_file = target
        return target


class RunFailed(HeliostepError):
    """The simulation failed or was interrupted part-way; ``result`` holds the incomplete run
    (``result.reason`` says which)."""

    def __init__(self, message: str, result: RunResult):
        super().__init__(message)
        self.result = result

    @property
    def interrupted(self) -> bool:
        return self.result.reason == "interrupted"


def _raise_input_error(exc: SimulationError, rows: int, scenario: Scenario) -> None:
    """An input error found while setting up the FMUs (e.g. an unknown parameter name), before
    any row was computed (``rows`` computed), is bad input (exit 2), not a failed simulation."""
    cause = exc.__cause__
    if getattr(exc, "reason", "failed") == "failed" and isinstance(cause, InputError) and not rows:
        raise InputError(f"{scenario.source}: {cause}") from None


def _sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _check_roles(roles: dict[str, str], infos: dict[str, FMUInfo], scenario: Scenario) -> None:
    """Every role names a variable its FMU has, with the right causality."""
    expected = {**{r: "input" for r in INPUT_ROLES}, **{r: "output" for r in OUTPUT_ROLES},
                **{r: "parameter" for r in PARAMETER_ROLES}}
    for role, target in roles.items():
        instance, _, variable = target.partition(".")
        info = infos[instance]
        if variable not in info.variables:
            if role not in scenario.roles.model_fields_set:
                continue  # a default role this FMU does not have: absent
            raise InputError(f"{scenario.source}: roles.{role}: {info.path.name} (instance {instance!r}) has no "
                             f"variable {variable!r}; its {expected[role]}s: {', '.join(info.names(expected[role]))}")
        causality = info.variables[variable].causality
        if causality != expected[role]:
            raise InputError(f"{scenario.source}: roles.{role}: {target} has causality {causality!r}, "
                             f"expected {expected[role]!r}")


def _present_roles(scenario: Scenario, infos: dict[str, FMUInfo]) -> dict[str, str]:
    """The scenario's roles that exist in its FMUs (checked), resolved once for the whole run."""
    roles = scenario.resolved_roles()
    _check_roles(roles, infos, scenario)
    return {role: target for role, target in roles.items()
            if target.partition(".")[2] in infos[target.partition(".")[0]].variables}


def _parameters(scenario: Scenario, inputs: DriveInputs, roles: dict[str, str], infos: dict) -> dict:
    """Parameters per instance: what the scenario implies (through the parameter roles), then the user's."""
    parameters = {name: dict(scenario.parameters.get(name, {})) for name in infos}
    transmission_keys = {"pinion_radius": "transmission.pinion_radius", "lever_arm": "transmission.lever_arm"}
    for role, value in inputs.implied_parameters.items():
        if role not in roles:
            continue
        instance, _, name = roles[role].partition(".")
        user = scenario.parameters.get(instance, {})
        if role in transmission_keys and name in user and user[name] != value:
            raise InputError(f"{scenario.source}: parameters.{instance}.{name} = {user[name]} contradicts "
                             f"{transmission_keys[role]} = {value}; set the transmission in "
                             f"{transmission_keys[role]} only")
        parameters[instance].setdefault(name, value)
    return parameters


def _signals(inputs: DriveInputs, roles: dict[str, str]) -> list[PiecewiseConstant]:
    """The drive's commands as the master's input signals, into the FMU inputs their roles name.

    With idle current reduction the currents also drop to their idle fraction a set time after
    each step (:func:`heliostep.drive.sequencer.idle_currents`); those instants are events too.
    """
    steps, current_a, current_b = inputs.schedule.times, inputs.current_a_ref, inputs.current_b_ref
    if inputs.sequencer.idle_current_fraction != 1.0:
        times, current_a, current_b = idle_currents(inputs.schedule, inputs.sequencer, inputs.duration)
        steps = np.asarray(times[1:], dtype=float)
    signals = [PiecewiseConstant("i_a_ref", roles["current_a_ref"], steps, np.asarray(current_a, dtype=float)),
               PiecewiseConstant("i_b_ref", roles["current_b_ref"], steps, np.asarray(current_b, dtype=float))]
    if "wind_moment" in roles:
        signals.append(PiecewiseConstant("m_ext", roles["wind_moment"], np.zeros(0), np.array([inputs.wind_moment])))
    elif inputs.wind_moment != 0.0:
        raise InputError(f"wind.moment = {inputs.wind_moment} N.m, but no FMU input has the role wind_moment "
                         f"(roles.wind_moment)")
    return signals


def resolve_fmus(scenario: Scenario) -> dict[str, Path]:
    """Instance -> FMU file of a scenario, built when it is a model (an error names ``fmus.NAME``).

    A bare name is a model (built into the FMU cache) or an FMU in ``fmus/`` beside the scenario,
    in ``fmus/`` of the current directory, or in the FMU cache.
    """
    search = (scenario.folder / "fmus", Path.cwd() / "fmus")
    paths = {}
    for name in scenario.fmus:
        try:
            paths[name] = ensure_fmu(scenario.fmu_reference(name), search)
        except InputError as exc:
            raise InputError(f"{scenario.source}: fmus.{name}: {exc}") from None
    return paths


def run_scenario(scenario: Scenario | str | Path, overrides: tuple[str, ...] = (),
                 progress: bool = False, should_stop: Callable[[], bool] | None = None,
                 trace_dir: str | Path | None = None, stream: bool | None = None,
                 row_group_rows: int = ROW_GROUP_ROWS, keep_trace: bool = True) -> RunResult:
    """Run a scenario (an object or a YAML path with ``--set``-style overrides).

    Raises :class:`RunFailed` (carrying the incomplete :class:`RunResult`) when the
    simulation fails part-way, and :class:`~heliostep.errors.InputError` for bad input.
    ``should_stop`` is asked between solver calls; when it returns True the run stops there and
    :class:`RunFailed` carries the trace so far with ``reason == "interrupted"``.

    A window longer than :data:`HELD_TRACE_MAX_DURATION` (or any window with ``stream=True``)
    streams its trace while simulating to a Parquet file of ``row_group_rows`` rows per row
    group, under a temporary name in ``trace_dir`` (the output folder; :meth:`RunResult.write`
    renames it into place) or, without one, in a temporary folder removed with the result. The
    file's metadata says ``complete`` (or why not) once the run has ended, also when it failed
    or was interrupted. With ``stream=False`` the trace is held in memory whatever the window.
    The figures after the simulation (summary, light, holding) are evaluated in chunks of
    ``row_group_rows`` rows, a streamed trace read back one row group at a time, so held and
    streamed runs with the same ``row_group_rows`` give the same figures bit for bit.

    With ``keep_trace=False`` (a sweep's cases) no trace is kept: the rows go to the figures as
    they come (:class:`~heliostep.results.run_figures.FigureStream`), nothing is written, and the
    figures are those the run would give with its trace kept, bit for bit. The result then has
    no trace and draws no plots; an interrupted run's summary is not corrected for the step in
    progress at the cut (that needs the rows before it).
    """
    if not isinstance(scenario, Scenario):
        scenario = load_scenario(scenario, overrides)
    started = clock.perf_counter()
    fmu_paths = resolve_fmus(scenario)
    infos = {}
    for name, path in fmu_paths.items():
        try:
            infos[name] = read_fmu(path)  # FMI 2.0 ME, a binary for this platform that loads
        except InputError as exc:
            raise InputError(f"{scenario.source}: fmus.{name}: {exc}") from None
    roles = _present_roles(scenario, infos)
    try:  # a weather file that cannot be read, is for another site or misses the window: bad input, found now
        weather = load_weather(scenario)  # read once: the light figures take it from here
    except InputError as exc:
        raise InputError(f"{scenario.source}: optics.{exc}") from None
    inputs = prepare_inputs(scenario)
    parameters = _parameters(scenario, inputs, roles, infos)
    try:  # connections (types, units, loops), parameter names and values, checked before simulating
        system = CoSimulation(infos, [Connection(s, t) for s, t in scenario.connection_pairs()],
                              _signals(inputs, roles), parameters)
    except InputError as exc:
        raise InputError(f"{scenario.source}: {exc}") from None
    solver = SolverOptions(rtol=scenario.solver.rtol, atol=scenario.solver.atol,
                           max_step=scenario.solver.max_step or float("inf"),
                           max_num_steps=scenario.solver.max_num_steps)
    units = dict(UNITS)
    for name, info in infos.items():
        units.update({f"{name}.{v}": info.variables[v].unit for v in info.outputs if info.variables[v].unit})
    meta = {
        "heliostep": __version__, "python": platform.python_version(),
        "packages": {p: package_metadata.version(p) for p in VERSIONED_PACKAGES},
        "scenario": scenario.resolved_dict(), "fmus": {
            name: {"path": str(path), "sha256": _sha256(path), "guid": infos[name].guid}
            for name, path in fmu_paths.items()},
        "parameters": parameters, "roles": roles, "drive": drive_metadata(inputs),
        "window_start": inputs.window_start.isoformat(), "timezone": scenario.site.timezone, "units": units,
    }

    bar = _progress_bar(inputs.duration) if progress else None
    columns = ["time"] + [item.name for item in system.inputs]  # the master's trace columns
    columns += [f"{name}.{output}" for name, info in system.fmus.items() for output in info.traced_outputs]
    solution = SolutionRecorder(columns, roles, inputs.sequencer, inputs.schedule, inputs.panel_reference())
    assembler = TraceAssembler(inputs, roles)
    streamed = inputs.duration > HELD_TRACE_MAX_DURATION if stream is None else stream
    sink, temporary = None, None
    if not keep_trace:
        sink = FigureStream(columns, assembler, figure_columns(roles), meta, scenario, weather, row_group_rows)
    elif streamed:
        if trace_dir is None:
            temporary = Path(tempfile.mkdtemp(prefix=f"heliostep-trace-{scenario.name}-"))
        folder = Path(trace_dir) if trace_dir is not None else temporary
        sink = TraceStream(folder / f"{TMP_PREFIX}{os.getpid()}-{clock.time_ns():x}-trace.parquet", columns,
                           assembler, row_group_rows)
    prepared = _PreparedRun(scenario, system, inputs, solver, roles, meta, started, weather, row_group_rows, solution,
                            assembler, sink, temporary)
    try:
        run = _simulate_and_summarize(prepared, bar, should_stop)
    except BaseException:  # no result (a bug, bad input found late, a forced stop): its stream goes too
        if isinstance(sink, TraceStream):
            sink.abort()
        if temporary is not None:
            shutil.rmtree(temporary, ignore_errors=True)
        raise
    if not run.complete:
        raise RunFailed(run.error, run)
    return run


@dataclass
class _PreparedRun:
    """A run checked and set up by :func:`run_scenario`, ready to simulate."""

    scenario: Scenario
    system: CoSimulation
    inputs: DriveInputs
    solver: SolverOptions
    roles: dict
    meta: dict  # the run's metadata, completed by the simulation
    started: float  # [s] perf_counter at the start of run_scenario
    weather: object  # the weather file already read (None: clear sky)
    row_group_rows: int
    solution: SolutionRecorder  # the figures from every solver step
    assembler: TraceAssembler
    sink: TraceStream | FigureStream | None = None  # a streamed trace's file, or the figures of a run without trace
    temporary: Path | None = None  # the stream's own folder, without an output folder


def _simulate_and_summarize(prepared: _PreparedRun, bar, should_stop) -> RunResult:
    """The co-simulation, the trace (held, or finished in its stream) and the figures, as a RunResult."""
    scenario, system, inputs, solver, roles, meta = (prepared.scenario, prepared.system, prepared.inputs,
                                                     prepared.solver, prepared.roles, prepared.meta)
    solution, assembler, sink, weather = prepared.solution, prepared.assembler, prepared.sink, prepared.weather
    error, complete, reason, reached = None, True, None, None
    try:
        result = system.simulate(0.0, inputs.duration, inputs.output_times, solver,
                                 progress=bar.update_to if bar else None, should_stop=should_stop,
                                 monitor=solution,  # every solver step, for the figures
                                 sink=sink, sink_rows=SINK_ROWS)  # with a sink, the rows stream to the file
        raw, statistics = result.trace, result.statistics
    except SimulationError as exc:
        raw, statistics, error, complete = exc.trace, exc.statistics, str(exc), False
        reason = getattr(exc, "reason", "failed")
        reached = getattr(exc, "time", None)
        rows = sink.rows if sink is not None else len(raw)
        if reached is None or not np.isfinite(reached):
            last = sink.last_time if sink is not None else (float(raw["time"].iloc[-1]) if len(raw) else None)
            reached = last if last is not None else 0.0
        _raise_input_error(exc, rows, scenario)
    finally:
        if bar:
            bar.close()
    if isinstance(sink, TraceStream):
        try:
            sink.flush()  # the last rows: a write failing here fails the run as one during it
        except TraceWriteError:
            pass
        if sink.failed is not None:  # the file keeps the row groups written before the failure
            complete, reason, reached = False, "failed", sink.written_time or 0.0
            error = (f"the trace could not be written: {sink.failed}; it keeps the {sink.written_rows} rows "
                     f"up to t = {reached:.9g} s, not the rows computed after them (at least "
                     f"{sink.rows_not_written})")
    meta["statistics"] = {**statistics, "run_wall_time": clock.perf_counter() - prepared.started,
                          "peak_rss_mb_simulating": _peak_rss_mb()}
    if statistics.get("terminated"):  # an FMU asked to stop: the run ends there, normally
        meta["terminated"] = {"by": statistics.get("termination_reason"), "time_s": statistics.get("termination_time")}
    if len(solution):  # figures from every solver step, stored so summarize(trace, meta) recomputes them
        if list(raw.columns) != solution.columns:
            raise RuntimeError(f"solution recorder columns {solution.columns} differ from the trace's {list(raw.columns)}")
        meta["solution_figures"] = solution.figures()
    held, trace_file = None, None
    if sink is None:
        held = assembler(raw)
    elif isinstance(sink, TraceStream):  # the file is finished (its metadata says how the run ended)
        trace_file = sink.close(trace_metadata(scenario.name, meta, sink.columns, complete, reason, reached, error))
    # summary, light on the tube, holding vs wind: in chunks of row_group_rows rows, a streamed
    # trace read back one row group at a time (only the figures' columns); without a trace, as
    # the rows came
    if isinstance(sink, FigureStream):
        figures = sink.accumulator
    else:
        figures = run_figures(held if held is not None else trace_file, figure_columns(roles), meta, scenario,
                              weather, prepared.row_group_rows)
    summary = figures.figures()
    meta["statistics"]["figure_rows_held_max"] = figures.max_rows_held  # trace rows held at once for them
    meta["statistics"]["figure_step_rows_held_max"] = figures.summary.max_step_rows
    run = RunResult(scenario, held, summary, meta, complete, error, inputs, reason, reached,
                    trace_file=trace_file, temporary_folder=prepared.temporary, weather=weather,
                    trace_kept=not isinstance(sink, FigureStream))
    return run


def _peak_rss_mb() -> float | None:
    """The process's peak resident memory so far [MB] (None where the OS does not say)."""
    try:
        import resource
    except ImportError:  # not on Windows
        return None
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return round(peak / (1024 * 1024 if sys.platform == "darwin" else 1024), 1)  # bytes on macOS, KiB on Linux


def _progress_bar(duration: float):
    """A tqdm bar over simulated time when on a terminal and not in CI (shown after 2 s); else None."""
    if not sys.stderr.isatty() or os.environ.get("CI"):
        return None
    from tqdm import tqdm

    class Bar(tqdm):
        def update_to(self, t: float) -> None:
            if t - self.n >= 0.01 * self.total or t >= self.total:
                self.update(t - self.n)

    return Bar(total=duration, unit="s", desc="simulating", mininterval=0.5, delay=2.0,
               bar_format="{l_bar}{bar}| {n:.1f}/{total:.1f} s simulated [{elapsed}<{remaining}]")
