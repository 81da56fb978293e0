"""``heliostep run``: run one scenario and write its trace, figures, metadata and plots."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from heliostep.cli.band import add_band_options, prepare_band, run_band_after
from heliostep.cli.signals import ForcedStop, stop_requests
from heliostep.drive.sequencer import PreparationStopped
from heliostep.results.output.files import TMP_PREFIX, check_out_name
from heliostep.results.output.folder import owned_folder
from heliostep.results.output.rescue import rescue_folder
from heliostep.results.output.run_files import run_file_names, write_stopped_records
from heliostep.results.trace.files import TraceWriteError
from heliostep.run import RunFailed, RunOptions, RunResult, resolve_fmus, run_scenario
from heliostep.run.estimate import check_budget, estimate_run
from heliostep.run.runner import HELD_TRACE_MAX_DURATION
from heliostep.run.supervision.supervisor import DEFAULT_WATCHDOG
from heliostep.scenario import load_scenario

#: Windows longer than this [s] get no CSV copy of the trace unless --csv is given.
CSV_DEFAULT_MAX_DURATION = 3600.0

#: --fail-on's names -> the summary.json count each one fails on (when above 0).
FAIL_ON = {"lost-steps": "steps_lost", "missed-steps": "missed_steps"}

#: The exit status of a run written in full whose summary shows what --fail-on names (no other status uses it).
FAIL_ON_STATUS = 3


RUN_DESCRIPTION = (
    "Co-simulate a scenario and write trace.parquet, trace.csv (see --csv), summary.json, "
    "metadata.json and the figures into --out.\n\n"
    "The run holds --out's lock (.heliostep-lock) for its life: a second run into it is "
    "refused. Its files are written into a staging folder and swapped in; "
    ".heliostep-manifest.json lists them, and a rerun removes or replaces only the files an "
    "earlier run listed there (a file of the same name heliostep did not write is refused, "
    "never overwritten). --out is checked before simulating.\n\n"
    "Ctrl+C (SIGINT), SIGTERM or SIGHUP stops the simulation at the next safe point: the trace so "
    "far, summary.json and metadata.json are written, marked complete: false with reason "
    "interrupted and the time reached; no figures are drawn. A second one exits at once: "
    "files not finished are removed, none is left claiming to be complete.\n\n"
    "Before anything is computed, the run's steps, trace rows, memory and disk are estimated "
    "from the scenario; a run over its budget (budget.memory_gb, budget.disk_gb, or "
    "--max-memory / --max-disk) is refused with exit 2, naming the key that makes it large.\n\n"
    "Windows over 1 h stream the trace to trace.parquet (row groups, written as the rows "
    "come) instead of holding it in memory.\n\n"
    "A window with the sun below the horizon throughout runs, with a warning on stderr "
    'and "night": true and a warning in summary.json.\n\n'
    "--fail-on lost-steps,missed-steps makes a complete run whose summary counts steps lost or missed (any of "
    "those named) exit 3, everything written as usual, for a CI job.\n\n"
    "Exit status: 0 complete; 1 the simulation failed part-way (an FMU crashed, hung or asked to terminate "
    "before the window's end included; the trace so far is "
    "written, complete: false) or the results could not be written; 2 bad input "
    "(scenario, override, FMU, unusable --out, over the budget, an unknown --fail-on name); 3 complete and "
    "written, with the steps --fail-on names lost or missed; 130 / 143 / 129 stopped by SIGINT / SIGTERM / SIGHUP."
)


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        "run",
        help="run a scenario YAML: trace, summary.json, plots and metadata",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description=RUN_DESCRIPTION,
    )
    parser.add_argument("scenario", type=Path, help="scenario YAML file")
    parser.add_argument("--out", help="output folder (default: out/<scenario name>)")
    parser.add_argument(
        "--set",
        dest="overrides",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="override a scenario key, e.g. --set fmus.motor=StepperMotorIdealCurrent",
    )
    parser.add_argument(
        "--motor",
        metavar="NAME",
        help="a catalogue motor by name (heliostep motors lists them): its R, L, k_e, N_c, bus, T_d, rotor inertia "
        "and step angle set on the scenario (as heliostep size sets a candidate), before --set; recorded in "
        "metadata.json's motor",
    )
    parser.add_argument(
        "--current",
        type=float,
        metavar="A",
        help="the phase current [A] (sequencer.current), with or without --motor (default: the scenario's)",
    )
    parser.add_argument(
        "--catalogue",
        type=Path,
        default=None,
        help="--motor's catalogue (default heliostep/data/motors.yaml)",
    )
    parser.add_argument("--no-plots", action="store_true", help="skip the PNG figures")
    parser.add_argument(
        "--max-memory",
        type=float,
        metavar="GB",
        help="memory budget: a run estimated to need more is refused before it starts (budget.memory_gb, default 4)",
    )
    parser.add_argument(
        "--max-disk",
        type=float,
        metavar="GB",
        help="disk budget for the trace and records (budget.disk_gb, default 10)",
    )
    parser.add_argument(
        "--csv",
        action=argparse.BooleanOptionalAction,
        default=None,
        help="also write the trace as trace.csv (default: only for windows up to "
        f"{CSV_DEFAULT_MAX_DURATION / 3600:g} h; trace.parquet is always written)",
    )
    _add_fail_on_option(parser)
    _add_supervision_options(parser)
    add_band_options(parser)
    parser.set_defaults(func=_run_command)


def _add_fail_on_option(parser: argparse.ArgumentParser) -> None:
    """--fail-on WHAT[,WHAT]: the summary's counts that make a complete run exit :data:`FAIL_ON_STATUS`."""
    parser.add_argument(
        "--fail-on",
        type=_fail_on,
        default=(),
        metavar="WHAT[,WHAT]",
        help=f"exit {FAIL_ON_STATUS} when the complete run's summary counts any of these (after writing everything): "
        f"{', '.join(FAIL_ON)}",
    )


def _add_supervision_options(parser: argparse.ArgumentParser) -> None:
    """--supervise / --no-supervise and --watchdog."""
    parser.add_argument(
        "--supervise",
        action=argparse.BooleanOptionalAction,
        default=True,
        help="simulate in a supervised child process, so that an FMU that crashes, exits or hangs ends the run "
        "with exit status 1, named, and the trace so far (default: on)",
    )
    parser.add_argument(
        "--watchdog",
        type=_positive_seconds,
        default=DEFAULT_WATCHDOG,
        metavar="SECONDS",
        help=f"with --supervise: an FMU with no FMI call begun for this long hangs (default: {DEFAULT_WATCHDOG:g})",
    )


def _positive_seconds(text: str) -> float:
    """A positive number of seconds (argparse type: exit 2 naming the option otherwise)."""
    try:
        value = float(text)
    except ValueError:
        value = float("nan")
    if not value > 0:  # (nan too)
        raise argparse.ArgumentTypeError(f"{text} s; expected a positive number of seconds")
    return value


def _fail_on(text: str) -> tuple[str, ...]:
    """--fail-on's comma list of names (argparse type: exit 2 naming an unknown one)."""
    names = tuple(name.strip() for name in text.split(","))
    unknown = [name for name in names if name not in FAIL_ON]
    if unknown:
        raise argparse.ArgumentTypeError(
            f"{', '.join(map(repr, unknown))}: expected a comma list of {', '.join(FAIL_ON)}"
        )
    return names


def _failed_on(names: tuple[str, ...], summary: dict) -> int:
    """0, or :data:`FAIL_ON_STATUS` when the summary counts any of ``names`` (said on stderr)."""
    counts = {name: summary.get(FAIL_ON[name]) or 0 for name in dict.fromkeys(names)}
    found = {name: count for name, count in counts.items() if count > 0}
    if not found:
        return 0
    said = ", ".join(f"{count} {name.replace('-', ' ')}" for name, count in found.items())
    print(f"heliostep run: --fail-on: {said} (exit {FAIL_ON_STATUS})", file=sys.stderr)
    return FAIL_ON_STATUS


def _run_command(args: argparse.Namespace) -> int:
    with stop_requests() as stop:
        out_name = check_out_name(args.out) if args.out is not None else None  # "" refused before anything
        motor, motor_items = _catalogue_motor(args)
        scenario = load_scenario(args.scenario, [*motor_items, *args.overrides, *_budget_overrides(args)])
        # the estimate first: a run too large for the budget is exit 2 before any work
        check_budget(scenario, estimate_run(scenario, HELD_TRACE_MAX_DURATION, csv=args.csv))
        out_dir = out_name or Path("out") / scenario.name
        fmu_paths = resolve_fmus(scenario)  # bad input found before --out is touched; resolved once per run
        band = prepare_band(args, scenario, fmu_paths)  # --band's design and keys checked before any run
        # the folder's lock, for the run's life; a folder made here and left empty by bad input is removed
        with owned_folder(out_dir, run_file_names(plots=not args.no_plots, csv=args.csv is not False)):
            return _run_in_folder(args, scenario, out_dir, fmu_paths, stop, band, motor)


def _catalogue_motor(args: argparse.Namespace) -> tuple[dict | None, list[str]]:
    """--motor's catalogue entry (its record for metadata.json, or None) and the ``--set`` items of --motor and
    --current (:func:`heliostep.scenario.catalogue.motor_overrides`: the items ``heliostep size`` sets)."""
    current = [] if args.current is None else [f"sequencer.current={args.current!r}"]
    if args.motor is None:
        return None, current
    from heliostep.scenario.catalogue import load_catalogue, motor_overrides, shipped_catalogue_path

    (candidate,) = load_catalogue(args.catalogue, [args.motor])  # unknown: exit 2 naming it and close names
    base = load_scenario(args.scenario, args.overrides)  # which instances play the motor and the mechanics
    record = {**candidate.record(), "catalogue": str(args.catalogue or shipped_catalogue_path())}
    return {**record, "current_A": args.current}, [*motor_overrides(base, candidate), *current]


def _budget_overrides(args: argparse.Namespace) -> list[str]:
    """--max-memory / --max-disk as the scenario keys they set."""
    given = (("budget.memory_gb", args.max_memory), ("budget.disk_gb", args.max_disk))
    return [f"{key}={value!r}" for key, value in given if value is not None]


def _run_in_folder(
    args: argparse.Namespace, scenario, out_dir: Path, fmu_paths, stop, band=None, motor: dict | None = None
) -> int:
    """The run simulated and written into ``out_dir`` (whose lock is held), then its --band; ``motor``: the
    catalogue entry of --motor, recorded in its metadata."""
    if stop.is_set():
        print(f"heliostep run: stopped by {stop.name} before simulating", file=sys.stderr)
        return _write_stopped(out_dir, stop, "starting", "before simulating")
    try:  # a long window streams its trace into out_dir while simulating (bounded memory)
        options = RunOptions(
            progress=True,
            should_stop=stop.is_set,
            trace_dir=out_dir,
            fmu_paths=fmu_paths,
            supervise=args.supervise,
            watchdog=args.watchdog,
        )
        result = run_scenario(scenario, options)
        status = 0
    except PreparationStopped:
        print(f"heliostep run: stopped by {stop.name} while preparing the inputs (nothing computed)", file=sys.stderr)
        return _write_stopped(out_dir, stop, "preparing_inputs", "while preparing the inputs")
    except RunFailed as failed:
        result = failed.result
        if failed.interrupted:
            status = stop.exit_status
            print(
                f"heliostep run: stopped by {stop.name or 'a stop request'} at t = "
                f"{result.time_reached:.6g} s; writing the trace so far (complete: false)",
                file=sys.stderr,
            )
        else:
            status = 1
            print(f"heliostep run: error: {failed}", file=sys.stderr)
    except OSError as exc:  # the streamed trace could not be written, or a file elsewhere (named: not --out)
        elsewhere = exc.filename is not None and out_dir.resolve() not in Path(exc.filename).resolve().parents
        what = f"{exc.filename}" if elsewhere else f"the trace to {out_dir}"
        print(f"heliostep run: error: could not write {what}: {exc}", file=sys.stderr)
        return 1
    if motor is not None:
        result.metadata["motor"] = motor
    _warn(result)
    failure_status = _write_results(args, result, out_dir, stop, status)
    if failure_status is not None:
        return failure_status
    if band is not None:  # the band runs after a complete nominal run only
        status = run_band_after(args, band, result, out_dir, fmu_paths, stop, status)
    if stop.is_set() and status == 0:
        print(
            f"heliostep run: stopped by {stop.name} while writing; the results are complete, "
            f"the figures may be missing",
            file=sys.stderr,
        )
        status = stop.exit_status
    return status or _failed_on(args.fail_on, result.summary)


def _write_stopped(out_dir: Path, stop, stage: str, when: str) -> int:
    """summary.json and metadata.json of a run stopped at ``stage``, before any simulation (complete: false):
    the stop's exit status, whether or not they could be written (said on stderr when not)."""
    try:
        write_stopped_records(out_dir, f"stopped by {stop.name or 'a stop request'} {when}", stage)
    except OSError as exc:
        print(f"heliostep run: error: could not write summary.json to {out_dir}: {exc}", file=sys.stderr)
    return stop.exit_status


def _write_results(args: argparse.Namespace, result: RunResult, out_dir: Path, stop, status: int) -> int | None:
    """The run's results written into ``out_dir`` (records, then the figures reported, then the plots drawn):
    None, or the exit status when they could not be written (rescued into a fresh folder)."""
    csv = args.csv
    if csv is None:
        duration = result.inputs.duration if result.inputs is not None else 0.0
        csv = duration <= CSV_DEFAULT_MAX_DURATION

    def report() -> None:  # the figures, as soon as the trace and records are written (the plots after)
        print(_report(result, out_dir), flush=True)

    try:
        plots = not args.no_plots
        result.write(out_dir, plots=plots, csv=csv, should_stop=stop.is_set, before_figures=report)
    except (OSError, TraceWriteError) as exc:  # a full disk, a file-size limit: a run failure, rescued
        print(f"heliostep run: error: could not write the results to {out_dir}: {exc}", file=sys.stderr)
        _rescue_into_a_fresh_folder(result, out_dir)
        return status or 1
    except ForcedStop:  # a second signal while writing: the stream cut short is not left in --out
        _discard_stream(result, out_dir)
        raise
    return None


def _warn(result: RunResult) -> None:
    """A window at night (the summary says so too), or a run that commanded no step."""
    if result.figures is not None and result.figures.night_warning:
        print(f"heliostep run: warning: {result.figures.night_warning}", file=sys.stderr)
    elif result.complete and result.inputs is not None and not len(result.inputs.schedule):
        increment = np.degrees(result.inputs.sequencer.increment)
        travel = np.degrees(np.ptp(result.inputs.rotor_angle_ref))
        print(
            f"heliostep run: warning: no step was commanded: the reference rotor angle moves {travel:.3g} deg "
            f"over the window, the sequencer steps {increment:.3g} deg (see transmission.pinion_radius, "
            "sequencer.step_angle, window)",
            file=sys.stderr,
        )


def _discard_stream(result: RunResult, out_dir: Path) -> None:
    """The run's streamed trace removed where it is still a temporary file in ``out_dir`` (not swapped in):
    a second stop signal asks for no more writing, and no file of heliostep's is left unlisted there."""
    stream = result.trace_file
    if stream is not None and stream.parent == out_dir and stream.name.startswith(TMP_PREFIX):
        stream.unlink(missing_ok=True)


def _rescue_into_a_fresh_folder(result: RunResult, out_dir: Path) -> None:
    """The results that ``out_dir`` could not take written to a rescue folder, and said where."""
    rescue = _rescue(result)
    if rescue:
        print(f"heliostep run: the results were written to {rescue} instead", file=sys.stderr)
        _discard_stream(result, out_dir)  # the stream cut short: its rows are in the rescue
    else:
        print("heliostep run: error: no folder could take the results either", file=sys.stderr)


def _rescue(result: RunResult) -> Path | None:
    """Every computed row and the records in a fresh folder that takes them (no figures; the trace
    in parts under a file-size limit, :meth:`RunResult.write_rescue`); None if nowhere does."""
    folder = rescue_folder(result.scenario.name)
    if folder is None:
        return None
    try:
        result.write_rescue(folder)
        return folder
    except (OSError, TraceWriteError) as exc:
        print(f"heliostep run: error: the rescue into {folder} failed too: {exc}", file=sys.stderr)
        return None


def _report(result: RunResult, out_dir: Path) -> str:
    s = result.summary
    state = (
        "complete"
        if result.complete
        else (
            f"INCOMPLETE ({result.reason or 'failed'} at t = {result.time_reached:.6g} s)"
            if result.time_reached is not None
            else "INCOMPLETE"
        )
    )
    lines = [f"{result.scenario.name}: {state} -> {out_dir}"]
    terminated = result.metadata.get("terminated")
    if terminated:  # an FMU ended the run (at the window's end the run is still complete): say which, when
        lines.append(
            f"  terminated by {', '.join(terminated.get('instances') or ['an FMU'])} at t = "
            f"{terminated.get('time_s') or 0.0:.6g} s (terminateSimulation)"
        )
    for key, label, fmt in (
        ("max_tracking_error_deg", "max tracking error [deg]", "{:.4f}"),
        ("rms_tracking_error_deg", "RMS tracking error [deg]", "{:.4f}"),
        ("peak_torque_Nm", "peak torque [N.m]", "{:.3f}"),
        ("peak_phase_current_A", "peak phase current [A]", "{:.3f}"),
        ("electrical_energy_J", "electrical energy [J]", "{:.1f}"),
        ("steps_commanded", "steps commanded", "{}"),
        ("steps_executed", "steps executed", "{}"),
        ("missed_steps", "missed steps", "{}"),
        ("steps_lost", "steps lost", "{}"),
        ("drive_energy_per_day_J", "drive energy per day [J]", "{:.0f}"),
        ("drive_energy_24h_J", "  over 24 h, with the night [J]", "{:.0f}"),
        ("idle_holding_margin", "idle holding / wind moment", "{:.2f}"),
        ("light_energy_J", "light on the tube [J]", "{:.4g}"),
        ("light_energy_ideal_J", "  with ideal tracking [J]", "{:.4g}"),
        ("light_stepping_change_J", "  change from stepping [J]", "{:+.3g}"),
        ("light_lost_shared_primary_J", "  lost to the shared primary [J]", "{:.3g}"),
        ("mean_intercept", "mean intercept factor", "{:.3f}"),
        ("wind_peak_moment_Nm", "peak wind moment [N.m]", "{:.3g}"),
        ("stowed_time_s", "stowed [s]", "{:.1f}"),
        ("light_lost_stowed_J", "  light lost while stowed [J]", "{:.4g}"),
    ):
        if s.get(key) is not None:
            lines.append(f"  {label:28s} {fmt.format(s[key])}")
    for move in s.get("stow_moves", []):
        lines.append(
            f"  {move['kind'] + ' move [s]':28s} {move['start_s']:.1f} - {move['end_s']:.1f}: "
            f"{move['steps_commanded']} steps, {move['missed_steps']} missed, {move['steps_lost']} lost"
        )
    wall = result.metadata.get("statistics", {}).get("run_wall_time")
    if wall is not None:
        lines.append(f"  {'wall time [s]':28s} {wall:.2f}")
    return "\n".join(lines)
