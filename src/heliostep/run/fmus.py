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

__all__ = ["fmu_records", "read_fmus", "resolve_fmus"]


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
    """Instance -> the FMU read (FMI 2.0 ME, a binary for this platform that loads, unpacking within
    ``budget.disk_gb``), or an InputError naming ``fmus.NAME``."""
    infos = {}
    max_unpacked_bytes = int(scenario.budget.disk_gb * 1e9)
    for name, path in fmu_paths.items():
        try:
            infos[name] = read_fmu(path, name in scenario.communication_interval, max_unpacked_bytes)
        except InputError as exc:
            raise InputError(f"{scenario.source}: fmus.{name}: {exc}") from None
    return infos


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
