"""``heliostep run``: run one scenario and write its trace, figures, metadata and plots."""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

from heliostep.cli.signals import stop_requests
from heliostep.errors import HeliostepError
from heliostep.results.outputs import check_out_dir
from heliostep.run import RunFailed, RunResult, resolve_fmus, run_scenario
from heliostep.run.supervised import DEFAULT_WATCHDOG
from heliostep.scenario import load_scenario

#: Windows longer than this [s] get no CSV copy of the trace unless --csv is given.
CSV_DEFAULT_MAX_DURATION = 3600.0


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        "run",
        help="run a scenario YAML: trace, summary.json, plots and metadata",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description="Co-simulate a scenario and write trace.parquet, trace.csv (see --csv), summary.json, "
        "metadata.json and the figures into --out.\n\n"
        "Every file is written under a temporary name and renamed into place; files of these "
        "kinds left in --out by an earlier run and not written now are removed. --out is "
        "checked before simulating.\n\n"
        "Ctrl+C (SIGINT) or SIGTERM stops the simulation at the next safe point: the trace so "
        "far, summary.json and metadata.json are written, marked complete: false with reason "
        "interrupted and the time reached; no figures are drawn. A second one exits at once: "
        "files not finished are removed, none is left claiming to be complete.\n\n"
        "Windows over 1 h stream the trace to trace.parquet (row groups, written as the rows "
        "come) instead of holding it in memory.\n\n"
        "A window with the sun below the horizon throughout runs, with a warning on stderr "
        'and "night": true and a warning in summary.json.\n\n'
        "Exit status: 0 complete; 1 the simulation failed part-way (the trace so far is "
        "written, complete: false) or the results could not be written; 2 bad input "
        "(scenario, override, FMU, unusable --out); 130 / 143 stopped by SIGINT / SIGTERM.",
    )
    parser.add_argument("scenario", type=Path, help="scenario YAML file")
    parser.add_argument("--out", type=Path, help="output folder (default: out/<scenario name>)")
    parser.add_argument(
        "--set",
        dest="overrides",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="override a scenario key, e.g. --set fmus.motor=StepperMotorIdealCurrent",
    )
    parser.add_argument("--no-plots", action="store_true", help="skip the PNG figures")
    parser.add_argument(
        "--csv",
        action=argparse.BooleanOptionalAction,
        default=None,
        help="also write the trace as trace.csv (default: only for windows up to "
        f"{CSV_DEFAULT_MAX_DURATION / 3600:g} h; trace.parquet is always written)",
    )
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
    parser.set_defaults(func=_run_command)


def _positive_seconds(text: str) -> float:
    """A positive number of seconds (argparse type: exit 2 naming the option otherwise)."""
    try:
        value = float(text)
    except ValueError:
        value = float("nan")
    if not value > 0:  # (nan too)
        raise argparse.ArgumentTypeError(f"{text} s; expected a positive number of seconds")
    return value


def _run_command(args: argparse.Namespace) -> int:
    with stop_requests() as stop:
        scenario = load_scenario(args.scenario, args.overrides)
        out_dir = args.out or Path("out") / scenario.name
        fmu_paths = resolve_fmus(scenario)  # bad input found before --out is touched; resolved once per run
        existed = out_dir.exists()
        check_out_dir(out_dir)
        if stop.is_set():
            print(f"heliostep run: stopped by {stop.name} before simulating", file=sys.stderr)
            return stop.exit_status
        try:  # a long window streams its trace into out_dir while simulating (bounded memory)
            supervision = {"supervise": args.supervise, "watchdog": args.watchdog}
            result = run_scenario(
                scenario, progress=True, should_stop=stop.is_set, trace_dir=out_dir, fmu_paths=fmu_paths, **supervision
            )
            status = 0
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
        except HeliostepError:
            if not existed:  # bad input found while setting up the FMUs: leave no empty folder
                _remove_if_empty(out_dir)
            raise
        except OSError as exc:  # the streamed trace could not be written
            print(f"heliostep run: error: could not write the trace to {out_dir}: {exc}", file=sys.stderr)
            return 1
        if result.figures is not None and result.figures.night_warning:  # the summary says so too
            print(f"heliostep run: warning: {result.figures.night_warning}", file=sys.stderr)
        csv = args.csv
        if csv is None:
            duration = result.inputs.duration if result.inputs is not None else 0.0
            csv = duration <= CSV_DEFAULT_MAX_DURATION
        try:
            result.write(out_dir, plots=not args.no_plots, csv=csv, should_stop=stop.is_set)
        except OSError as exc:
            print(f"heliostep run: error: could not write the results to {out_dir}: {exc}", file=sys.stderr)
            rescue = _rescue(result, csv)
            if rescue:
                print(f"heliostep run: the results were written to {rescue} instead", file=sys.stderr)
            return status or 1
        print(_report(result, out_dir))
        if stop.is_set() and status == 0:
            print(
                f"heliostep run: stopped by {stop.name} while writing; the results are complete, "
                f"the figures may be missing",
                file=sys.stderr,
            )
            status = stop.exit_status
    return status


def _remove_if_empty(folder: Path) -> None:
    try:
        folder.rmdir()
    except OSError:
        pass


def _rescue(result: RunResult, csv: bool) -> Path | None:
    """Write the results into a fresh temporary folder (no figures); None if that fails too."""
    try:
        rescue = Path(tempfile.mkdtemp(prefix=f"heliostep-{result.scenario.name}-"))
        result.write(rescue, plots=False, csv=csv)
        return rescue
    except OSError:
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
        ("idle_holding_margin", "idle holding / wind moment", "{:.2f}"),
        ("light_energy_J", "light on the tube [J]", "{:.4g}"),
        ("light_energy_ideal_J", "  with ideal tracking [J]", "{:.4g}"),
        ("light_stepping_change_J", "  change from stepping [J]", "{:+.3g}"),
        ("light_lost_shared_primary_J", "  lost to the shared primary [J]", "{:.3g}"),
        ("mean_intercept", "mean intercept factor", "{:.3f}"),
    ):
        if s.get(key) is not None:
            lines.append(f"  {label:28s} {fmt.format(s[key])}")
    wall = result.metadata.get("statistics", {}).get("run_wall_time")
    if wall is not None:
        lines.append(f"  {'wall time [s]':28s} {wall:.2f}")
    return "\n".join(lines)
