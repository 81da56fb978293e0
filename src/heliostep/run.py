"""``run_scenario``: heliostep's one public entry point, and ``heliostep run``.

scenario → inputs (:mod:`heliostep.drive.inputs`) → master (:mod:`heliostep.cosim.master`) → trace
(:mod:`heliostep.results.trace`) → summary (:mod:`heliostep.results.summary`) / plots (:mod:`heliostep.plots.run`).
A run that fails part-way still returns (and writes) the trace so far, marked incomplete.
"""

from __future__ import annotations

import hashlib
import json
import os
import platform
import sys
import time as clock
from dataclasses import dataclass, field
from importlib import metadata as package_metadata
from pathlib import Path

import numpy as np
import pandas as pd

from heliostep import __version__
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
from heliostep.errors import HeliostepError, InputError
from heliostep.fmu.build import ensure_fmu
from heliostep.results.summary import summarize
from heliostep.results.trace import UNITS, assemble_trace, drive_metadata
from heliostep.results.trace_io import write_trace
from heliostep.scenario import (
    INPUT_ROLES,
    OUTPUT_ROLES,
    PARAMETER_ROLES,
    Scenario,
    load_scenario,
)

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
        roles = {f"role.{r}": c for r, c in self.metadata.get("roles", {}).items() if c in self.trace}
        return {"complete": str(self.complete).lower(), "scenario": self.scenario.name,
                "window_start": self.metadata["window_start"], "timezone": self.metadata["timezone"],
                **({"error": self.error} if self.error else {}), **units, **roles}

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
    """The drive's commands as the master's input signals, into the FMU inputs their roles name."""
    steps = inputs.schedule.times
    signals = [PiecewiseConstant("i_a_ref", roles["current_a_ref"], steps, inputs.current_a_ref),
               PiecewiseConstant("i_b_ref", roles["current_b_ref"], steps, inputs.current_b_ref)]
    if "wind_moment" in roles:
        signals.append(PiecewiseConstant("m_ext", roles["wind_moment"], np.zeros(0), np.array([inputs.wind_moment])))
    elif inputs.wind_moment != 0.0:
        raise InputError(f"wind.moment = {inputs.wind_moment} N.m, but no FMU input has the role wind_moment "
                         f"(roles.wind_moment)")
    return signals


def run_scenario(scenario: Scenario | str | Path, overrides: tuple[str, ...] = (),
                 progress: bool = False) -> RunResult:
    """Run a scenario (an object or a YAML path with ``--set``-style overrides).

    Raises :class:`RunFailed` (carrying the incomplete :class:`RunResult`) when the
    simulation fails part-way, and :class:`~heliostep.errors.InputError` for bad input.
    """
    if not isinstance(scenario, Scenario):
        scenario = load_scenario(scenario, overrides)
    started = clock.perf_counter()
    search = (scenario.folder / "fmus", Path.cwd() / "fmus")
    fmu_paths = {name: ensure_fmu(scenario.fmu_reference(name), search) for name in scenario.fmus}
    infos = {name: read_fmu(path) for name, path in fmu_paths.items()}
    roles = _present_roles(scenario, infos)
    inputs = prepare_inputs(scenario)
    parameters = _parameters(scenario, inputs, roles, infos)
    system = CoSimulation(infos, [Connection(s, t) for s, t in scenario.connection_pairs()],
                          _signals(inputs, roles), parameters)
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
    trace = assemble_trace(raw, inputs, roles)
    meta["statistics"] = {**statistics, "run_wall_time": clock.perf_counter() - started}
    run = RunResult(scenario, trace, summarize(trace, meta) if len(trace) else {}, meta,
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
