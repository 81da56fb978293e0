"""``run_scenario``: heliostep's one public entry point, and ``heliostep run``.

scenario → inputs (:mod:`heliostep.inputs`) → master (:mod:`heliostep.master`) → trace
(:mod:`heliostep.trace`) → summary (:mod:`heliostep.summary`) / plots (:mod:`heliostep.plots.run`).
A run that fails part-way still returns (and writes) the trace so far, marked incomplete.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import platform
import sys
import time as clock
from dataclasses import dataclass, field
from importlib import metadata as package_metadata
from pathlib import Path

import pandas as pd

from heliostep import __version__
from heliostep.build import ensure_fmu
from heliostep.errors import HeliostepError, InputError
from heliostep.fmi import read_fmu
from heliostep.inputs import DriveInputs, prepare_inputs
from heliostep.master import CoSimulation, Connection, SimulationError, SolverOptions
from heliostep.scenario import Scenario, load_scenario
from heliostep.summary import summarize
from heliostep.trace import UNITS, assemble_trace
from heliostep.trace_io import write_trace

#: Packages whose versions go into a run's metadata.
VERSIONED_PACKAGES = ("fmpy", "pymoca", "casadi", "pvlib", "numpy", "scipy", "pandas")


@dataclass
class RunResult:
    """The outcome of :func:`run_scenario`.

    ``complete`` is False when the simulation failed part-way; ``error`` then says why and
    ``trace`` holds the rows computed until then.
    """

    scenario: Scenario
    trace: pd.DataFrame
    summary: dict
    metadata: dict
    complete: bool = True
    error: str | None = None
    inputs: DriveInputs | None = field(default=None, repr=False)

    def to_pandas(self) -> pd.DataFrame:
        """The trace as a DataFrame (a copy)."""
        return self.trace.copy()

    def plot(self, out_dir: str | Path) -> list[Path]:
        """Write the paper's Figs. 8–14 for this run into ``out_dir``."""
        from heliostep.plots.run import plot_run

        out_dir = Path(out_dir)
        out_dir.mkdir(parents=True, exist_ok=True)
        return plot_run(self.trace, out_dir, self.trace_metadata())

    def trace_metadata(self) -> dict[str, str]:
        units = {f"unit.{c}": u for c, u in self.metadata.get("units", {}).items() if c in self.trace}
        return {"complete": str(self.complete).lower(), "scenario": self.scenario.name,
                "window_start": self.metadata["window_start"], "timezone": self.metadata["timezone"],
                **({"error": self.error} if self.error else {}), **units}

    def write(self, out_dir: str | Path, plots: bool = True) -> dict[str, Path]:
        """Write trace (Parquet and CSV), summary.json, metadata.json and plots into ``out_dir``."""
        out_dir = Path(out_dir)
        out_dir.mkdir(parents=True, exist_ok=True)
        written = {}
        for suffix in ("parquet", "csv"):
            written[f"trace.{suffix}"] = write_trace(self.trace, out_dir / f"trace.{suffix}", self.trace_metadata())
        summary = {"complete": self.complete, "error": self.error, **self.summary}
        for name, content in (("summary.json", summary), ("metadata.json", self.metadata)):
            path = out_dir / name
            path.write_text(json.dumps(content, indent=2, default=str) + "\n")
            written[name] = path
        if plots and len(self.trace):
            for path in self.plot(out_dir):
                written[path.name] = path
        return written


class RunFailed(HeliostepError):
    """The simulation failed part-way; ``result`` holds the incomplete run."""

    def __init__(self, message: str, result: RunResult):
        super().__init__(message)
        self.result = result


def _sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _implied_parameters(scenario: Scenario, inputs: DriveInputs, infos: dict) -> dict:
    """Parameters per instance: what the scenario implies (those the FMU has), then the user's.

    The scenario implies the mechanics' initial panel angle and transmission and the
    motor's initial currents (the drive holds its first step at the window start).
    """
    parameters = {name: dict(scenario.parameters.get(name, {})) for name in infos}
    implied_by_role = {"mechanics": inputs.mechanics_parameters, "motor": inputs.motor_parameters}
    for role, implied in implied_by_role.items():
        if role not in infos:
            continue
        implied = {k: v for k, v in implied.items() if k in infos[role].parameters}
        user = parameters[role]
        for name, key in (("r", "transmission.pinion_radius"), ("s", "transmission.lever_arm")):
            if role == "mechanics" and name in user and name in implied and user[name] != implied[name]:
                raise InputError(f"parameters.mechanics.{name} = {user[name]} contradicts {key} = "
                                 f"{implied[name]}; set the transmission in {key} only")
        parameters[role] = {**implied, **user}
    return parameters


def run_scenario(scenario: Scenario | str | Path, overrides: tuple[str, ...] = (),
                 progress: bool = False) -> RunResult:
    """Run a scenario (an object or a YAML path with ``--set``-style overrides).

    Raises :class:`RunFailed` (carrying the incomplete :class:`RunResult`) when the
    simulation fails part-way, and :class:`~heliostep.errors.InputError` for bad input.
    """
    if not isinstance(scenario, Scenario):
        scenario = load_scenario(scenario, overrides)
    started = clock.perf_counter()
    fmu_paths = {name: ensure_fmu(scenario.fmu_reference(name)) for name in scenario.fmus}
    infos = {name: read_fmu(path) for name, path in fmu_paths.items()}
    fmu_inputs = frozenset(f"{name}.{variable}" for name, info in infos.items() for variable in info.inputs)
    inputs = prepare_inputs(scenario, fmu_inputs)
    parameters = _implied_parameters(scenario, inputs, infos)
    system = CoSimulation(infos, [Connection(s, t) for s, t in scenario.connection_pairs()],
                          inputs.signals, parameters)
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
        "parameters": parameters, "window_start": inputs.window_start.isoformat(),
        "timezone": scenario.site.timezone, "units": units,
    }

    bar = _progress_bar(inputs.duration) if progress else None
    error, complete = None, True
    try:
        result = system.simulate(0.0, inputs.duration, inputs.output_times, solver,
                                 progress=bar.update_to if bar else None)
        raw, statistics = result.trace, result.statistics
    except SimulationError as exc:
        raw, statistics, error, complete = exc.trace, exc.statistics, str(exc), False
    finally:
        if bar:
            bar.close()
    trace = assemble_trace(raw, inputs)
    meta["statistics"] = {**statistics, "run_wall_time": clock.perf_counter() - started}
    run = RunResult(scenario, trace, summarize(trace, inputs) if len(trace) else {}, meta,
                    complete, error, inputs)
    if not complete:
        raise RunFailed(error, run)
    return run


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
