"""``heliostep run``: run one scenario and write its trace, figures, metadata and plots."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from heliostep.run import RunFailed, RunResult, run_scenario
from heliostep.scenario import load_scenario


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        "run", help="run a scenario YAML: trace, summary.json, plots and metadata",
        description="Co-simulate a scenario and write trace.parquet, trace.csv, summary.json, "
                    "metadata.json and the figures into --out.")
    parser.add_argument("scenario", type=Path, help="scenario YAML file")
    parser.add_argument("--out", type=Path, help="output folder (default: out/<scenario name>)")
    parser.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                        help="override a scenario key, e.g. --set fmus.motor=StepperMotorIdealCurrent")
    parser.add_argument("--no-plots", action="store_true", help="skip the PNG figures")
    parser.set_defaults(func=_run_command)


def _run_command(args: argparse.Namespace) -> int:
    scenario = load_scenario(args.scenario, args.overrides)
    out_dir = args.out or Path("out") / scenario.name
    try:
        result = run_scenario(scenario, progress=True)
        status = 0
    except RunFailed as failed:
        result, status = failed.result, 1
        print(f"heliostep run: error: {failed}", file=sys.stderr)
    result.write(out_dir, plots=not args.no_plots)
    print(_report(result, out_dir))
    return status


def _report(result: RunResult, out_dir: Path) -> str:
    s = result.summary
    lines = [f"{result.scenario.name}: {'complete' if result.complete else 'INCOMPLETE'} -> {out_dir}"]
    for key, label, fmt in (("max_tracking_error_deg", "max tracking error [deg]", "{:.4f}"),
                            ("rms_tracking_error_deg", "RMS tracking error [deg]", "{:.4f}"),
                            ("peak_torque_Nm", "peak torque [N.m]", "{:.3f}"),
                            ("peak_phase_current_A", "peak phase current [A]", "{:.3f}"),
                            ("electrical_energy_J", "electrical energy [J]", "{:.1f}"),
                            ("steps_commanded", "steps commanded", "{}"),
                            ("steps_executed", "steps executed", "{}"),
                            ("missed_steps", "missed steps", "{}")):
        if s.get(key) is not None:
            lines.append(f"  {label:28s} {fmt.format(s[key])}")
    wall = result.metadata.get("statistics", {}).get("run_wall_time")
    if wall is not None:
        lines.append(f"  {'wall time [s]':28s} {wall:.2f}")
    return "\n".join(lines)
