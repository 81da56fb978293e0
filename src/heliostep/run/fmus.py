"""A scenario's FMUs: resolved to files (built when they are models) and read, once per run."""

from __future__ import annotations

import hashlib
from collections.abc import Mapping
from pathlib import Path

from heliostep.cosim import FMUInfo, read_fmu
from heliostep.errors import InputError
from heliostep.fmu.build import ensure_fmu
from heliostep.fmu.sources import with_platform_binary
from heliostep.paths import fmus_dir
from heliostep.scenario import Scenario

__all__ = ["FROM_FMU", "FROM_SCENARIO", "communication_intervals", "fmu_records", "read_fmus", "resolve_fmus"]

#: where a sampled component's communication interval came from (``metadata.json``'s ``communication_intervals``)
FROM_SCENARIO, FROM_FMU = "communication_interval", "the FMU's DefaultExperiment stepSize"


def resolve_fmus(scenario: Scenario) -> dict[str, Path]:
    """Instance -> FMU file of a scenario, built when it is a model (an error names ``fmus.NAME``).

    A bare name is a model in ``models/`` beside the scenario or in the models folder (built into the FMU
    cache), or an FMU in ``fmus/`` beside the scenario, in ``fmus/`` of the current directory, or in the FMU
    cache (:func:`~heliostep.fmu.build.variant_folders`). Each call hashes the models and
    asks the compiler its version: resolve once per run and pass the result on
    (``run_scenario(..., fmu_paths=...)``). An FMU that ships only its sources is compiled into the
    FMU cache on first use (:func:`~heliostep.fmu.sources.with_platform_binary`).
    """
    paths = {}
    for name in scenario.fmus:
        try:
            paths[name] = with_platform_binary(ensure_fmu(scenario.fmu_reference(name), scenario.folder), fmus_dir())
        except InputError as exc:
            raise InputError(f"{scenario.source}: fmus.{name}: {exc}") from None
    return paths


def read_fmus(scenario: Scenario, fmu_paths: Mapping[str, Path]) -> dict[str, FMUInfo]:
    """Instance -> the FMU read (FMI 2.0 or 3.0, a binary for this platform that loads, unpacking within
    ``budget.disk_gb``), or an InputError naming ``fmus.NAME``: as Co-Simulation where the scenario gives
    the instance a ``communication_interval``, else as the FMU offers (a Co-Simulation-only FMU that suggests a
    step runs as Co-Simulation at it; one that suggests none is refused naming ``communication_interval``)."""
    infos = {}
    max_unpacked_bytes = int(scenario.budget.disk_gb * 1e9)
    for name, path in fmu_paths.items():
        try:
            given = True if name in scenario.communication_interval else None
            infos[name] = read_fmu(path, given, max_unpacked_bytes)
        except InputError as exc:
            raise InputError(f"{scenario.source}: fmus.{name}: {exc}") from None
    return infos


def communication_intervals(scenario: Scenario, infos: Mapping[str, FMUInfo]) -> dict[str, tuple[float, str]]:
    """Instance -> (its communication interval [s], where it came from: :data:`FROM_SCENARIO` or
    :data:`FROM_FMU`) for every instance read as Co-Simulation (:func:`read_fmus`)."""
    intervals = {}
    for name, info in infos.items():
        if name in scenario.communication_interval:
            intervals[name] = (scenario.communication_interval[name], FROM_SCENARIO)
        elif info.co_simulation and info.default_step is not None:
            intervals[name] = (info.default_step, FROM_FMU)
    return intervals


def fmu_records(fmu_paths: Mapping[str, Path], infos: Mapping[str, FMUInfo]) -> dict[str, dict[str, str]]:
    """What a run's metadata says of each FMU: its path, SHA-256 and GUID."""
    return {
        name: {
            "path": str(path),
            "sha256": hashlib.sha256(Path(path).read_bytes()).hexdigest(),
            "guid": infos[name].guid,
        }
        for name, path in fmu_paths.items()
    }
