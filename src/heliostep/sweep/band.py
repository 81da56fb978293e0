"""Uncertainty bands: the ranges of the uncertain parameters and a Latin-hypercube design over them.

Details: docs/sweep.md, ``heliostep.sweep.band``.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from heliostep.cosim.fmi import read_fmu
from heliostep.errors import InputError
from heliostep.scenario import Scenario, read_yaml_file, set_dotted_key, validate_scenario

__all__ = [
    "DEFAULT_SEED",
    "MAX_BAND_SAMPLES",
    "RANGES_FILE",
    "BandDesign",
    "ParameterRange",
    "band_design",
    "check_sample_count",
    "load_ranges",
]

#: The shipped ranges file (package data).
RANGES_FILE = Path(__file__).resolve().parents[1] / "data" / "parameter_ranges.yaml"

#: The Latin hypercube's seed unless one is given (``--band-seed``).
DEFAULT_SEED = 21

#: The most samples a band may have (each sample is a run of the scenario).
MAX_BAND_SAMPLES = 1000

_ENTRY_KEYS = ("key", "low", "high", "unit", "source")


@dataclasses.dataclass(frozen=True)
class ParameterRange:
    """One uncertain parameter: its scenario key, range [unit] and source."""

    key: str
    low: float
    high: float
    unit: str
    source: str


def check_sample_count(n: int) -> int:
    """``n`` if it is a usable number of band samples (2 to :data:`MAX_BAND_SAMPLES`), else InputError."""
    if isinstance(n, bool) or not isinstance(n, int) or not 2 <= n <= MAX_BAND_SAMPLES:
        raise InputError(
            f"--band {n!r}: expected a whole number of samples from 2 to {MAX_BAND_SAMPLES} (each sample is a run)"
        )
    return n


def load_ranges(path: str | Path | None = None) -> tuple[ParameterRange, ...]:
    """The uncertain parameters of a ranges file (default :data:`RANGES_FILE`).

    Raises
    ------
    InputError
        Naming the file and the entry: not a ``ranges`` list, a missing or unknown field, a ``low``
        or ``high`` that is not a finite number, ``low`` not below ``high``, a key given twice.
    """
    path = Path(path) if path is not None else RANGES_FILE
    data = read_yaml_file(path, "ranges file")
    entries = data.get("ranges") if isinstance(data, dict) else None
    if not isinstance(entries, list) or not entries:
        raise InputError(f"{path}: expected a mapping with a non-empty list 'ranges' of {{{', '.join(_ENTRY_KEYS)}}}")
    ranges: list[ParameterRange] = []
    for index, entry in enumerate(entries):
        parameter = _range_entry(entry, f"{path}: ranges[{index}]")
        if any(known.key == parameter.key for known in ranges):
            raise InputError(f"{path}: ranges[{index}] ({parameter.key}): the key is given twice")
        ranges.append(parameter)
    return tuple(ranges)


def _range_entry(entry: Any, where: str) -> ParameterRange:
    """One entry of a ranges file, checked (``where`` names it in the error)."""
    if not isinstance(entry, dict):
        raise InputError(f"{where}: expected a mapping of {', '.join(_ENTRY_KEYS)}, got {entry!r}")
    key = entry.get("key")
    if not isinstance(key, str) or not all(part.strip() for part in key.split(".")):
        raise InputError(f"{where}: key: expected a dotted scenario key such as parameters.motor.V_supply, got {key!r}")
    where = f"{where} ({key})"
    unknown = sorted(set(entry) - set(_ENTRY_KEYS))
    if unknown:
        raise InputError(f"{where}: unknown field(s) {', '.join(unknown)}; expected {', '.join(_ENTRY_KEYS)}")
    bounds = []
    for bound in ("low", "high"):
        value = entry.get(bound)
        if bound not in entry:
            raise InputError(f"{where}: missing '{bound}': expected the {bound} end of the range (a number)")
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            raise InputError(f"{where}: {bound}: expected a finite number, got {value!r}")
        bounds.append(float(value))
    if not bounds[0] < bounds[1]:
        raise InputError(f"{where}: low = {bounds[0]:g} is not below high = {bounds[1]:g}")
    texts = []
    for field in ("unit", "source"):
        text = entry.get(field)
        if not isinstance(text, str) or not text.strip():
            raise InputError(f"{where}: {field}: expected a non-empty text (the {field} of the range)")
        texts.append(text.strip())
    return ParameterRange(key, bounds[0], bounds[1], texts[0], texts[1])


@dataclasses.dataclass(frozen=True)
class BandDesign:
    """The samples of a band: which keys vary over which ranges, and each sample's values.

    Attributes
    ----------
    ranges : tuple of ParameterRange
        The keys varied, in the order of the columns of ``values``.
    nominal : dict
        Key -> the scenario's own value [the range's unit].
    pinned : tuple of str
        Keys of the ranges file the scenario pins (``band.pinned``): not varied.
    seed : int
    values : numpy.ndarray
        (N, keys): sample i sets key j to ``values[i, j]``.
    ranges_file : str
    """

    ranges: tuple[ParameterRange, ...]
    nominal: dict[str, float]
    pinned: tuple[str, ...]
    seed: int
    values: np.ndarray
    ranges_file: str

    @property
    def samples(self) -> int:
        return int(self.values.shape[0])

    def settings(self, index: int) -> dict[str, float]:
        """Key -> value of sample ``index``."""
        return {parameter.key: float(self.values[index, j]) for j, parameter in enumerate(self.ranges)}

    def scenario_of(self, scenario: Scenario, index: int) -> Scenario:
        """``scenario`` with sample ``index``'s values set (validated; an InputError names the sample)."""
        data = scenario.resolved_dict()
        settings = self.settings(index)
        shown = ", ".join(f"{key}={value:.6g}" for key, value in settings.items())
        source = f"{scenario.source}: band sample {index} ({shown})"
        for key, value in settings.items():
            set_dotted_key(data, key.split("."), value, source)
        return validate_scenario(data, source=source, folder=scenario.folder)

    def record(self) -> dict[str, Any]:
        """The design as ``summary.json``'s ``band.design`` records it."""
        return {
            "method": "Latin hypercube (scipy.stats.qmc.LatinHypercube, scrambled): one sample in each of the "
            "N equal strata of each key's range",
            "samples": self.samples,
            "seed": self.seed,
            "ranges_file": self.ranges_file,
            "keys": [
                {
                    **dataclasses.asdict(parameter),
                    "nominal": self.nominal[parameter.key],
                    "nominal_in_range": parameter.low <= self.nominal[parameter.key] <= parameter.high,
                }
                for parameter in self.ranges
            ],
            "pinned": list(self.pinned),
            "values": [self.settings(index) for index in range(self.samples)],
        }


def band_design(
    scenario: Scenario,
    ranges: Sequence[ParameterRange],
    n: int,
    seed: int = DEFAULT_SEED,
    fmu_paths: Mapping[str, Path] | None = None,
    ranges_file: str | Path = RANGES_FILE,
) -> BandDesign:
    """N Latin-hypercube samples of ``ranges`` for ``scenario`` (its pinned keys left out).

    Parameters
    ----------
    scenario : Scenario
    ranges : sequence of ParameterRange
        From :func:`load_ranges`.
    n : int
        Samples, 2 to :data:`MAX_BAND_SAMPLES`.
    seed : int, default DEFAULT_SEED
        Seed of :class:`scipy.stats.qmc.LatinHypercube`.
    fmu_paths : Mapping, optional
        Instance -> FMU file (:func:`heliostep.run.resolve_fmus`): where a parameter the scenario does
        not set takes its nominal value (the FMU's start value) and is checked to exist.
    ranges_file : str or Path
        Named in error messages and recorded.

    Raises
    ------
    InputError
        A bad ``n``; a key the scenario does not have (no such FMU instance or parameter, no such
        scenario key, not a number), naming the key; a pinned key not in the ranges; every key pinned.
    """
    from scipy.stats import qmc

    check_sample_count(n)
    keys = {parameter.key for parameter in ranges}
    pinned = tuple(scenario.band.pinned)
    for key in pinned:
        if key not in keys:
            raise InputError(
                f"{scenario.source}: band.pinned: {key!r} is not a key of the ranges file {ranges_file} "
                f"(its keys: {', '.join(sorted(keys))})"
            )
    varied = tuple(parameter for parameter in ranges if parameter.key not in pinned)
    if not varied:
        raise InputError(f"{scenario.source}: band.pinned pins every key of {ranges_file}: nothing to vary")
    nominal = {
        parameter.key: nominal_value(scenario, parameter.key, fmu_paths or {}, ranges_file) for parameter in varied
    }
    unit = qmc.LatinHypercube(d=len(varied), scramble=True, seed=seed).random(n)
    low = np.array([parameter.low for parameter in varied])
    high = np.array([parameter.high for parameter in varied])
    return BandDesign(varied, nominal, pinned, int(seed), low + unit * (high - low), str(ranges_file))


def nominal_value(scenario: Scenario, key: str, fmu_paths: Mapping[str, Path], ranges_file: str | Path) -> float:
    """The scenario's value of a ranges-file ``key``: a ``parameters`` entry, else the FMU's start
    value; another key is looked up in the resolved scenario. An InputError names the key when the
    scenario does not have it."""
    where = f"{ranges_file}: {key}"
    parts = key.split(".")
    if parts[0] == "parameters":
        if len(parts) != 3:
            raise InputError(f"{where}: expected parameters.<instance>.<name>")
        instance, name = parts[1], parts[2]
        if instance not in scenario.fmus:
            raise InputError(
                f"{where}: the scenario {scenario.source} has no FMU instance {instance!r} "
                f"(its instances: {', '.join(scenario.fmus)})"
            )
        value = scenario.parameters.get(instance, {}).get(name)
        path = fmu_paths.get(instance)
        if path is not None:
            variable = read_fmu(path).variables.get(name)
            if variable is None or variable.causality != "parameter" or variable.type != "Real":
                raise InputError(
                    f"{where}: the FMU {Path(path).name} of instance {instance!r} ({scenario.source}) has no "
                    f"Real parameter {name!r}"
                )
            value = variable.start if value is None else value
    else:
        value = _lookup(scenario.resolved_dict(), parts)
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise InputError(f"{where}: the scenario {scenario.source} has no number at this key (found {value!r})")
    return float(value)


def _lookup(data: Any, parts: Sequence[str]) -> Any:
    for part in parts:
        if not isinstance(data, dict) or part not in data:
            return None
        data = data[part]
    return data
