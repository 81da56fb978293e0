"""The sun sensor presets: the SunSensor FMU's parameters of named sensors, read and checked from
``heliostep/data/sun_sensors.yaml``.

Details: docs/physics.md ("The sun sensor"), ``heliostep.scenario.sun_sensors``.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

from heliostep.errors import InputError
from heliostep.scenario.catalogue import close_names
from heliostep.scenario.yaml_io import read_yaml_file

__all__ = [
    "PARAMETER_KEYS",
    "SunSensorPreset",
    "load_sun_sensors",
    "shipped_sun_sensors_path",
    "sun_sensor",
]

#: The SunSensor FMU's parameters a preset sets, with their units (``models/SunSensor.mo``).
PARAMETER_KEYS: dict[str, str] = {"k_ray": "1", "fov": "rad", "offset": "rad", "threshold": "W/m2", "diffuse_view": "1"}
#: Every key of a preset: its source (text), the FMU's parameters and the random angle error ``noise_std`` [rad].
_TEXT_KEYS = ("maker", "document")
_KEYS = (*_TEXT_KEYS, *PARAMETER_KEYS, "noise_std")


@dataclass(frozen=True)
class SunSensorPreset:
    """One preset of the file.

    Attributes
    ----------
    name, maker, document : str
        The preset's name and where its values come from.
    parameters : dict of str to float
        The SunSensor FMU's parameters (:data:`PARAMETER_KEYS`, SI units).
    noise_std : float
        Standard deviation of the sensor's random error in its own angle e [rad]; not an FMU parameter.
    """

    name: str
    maker: str
    document: str
    parameters: dict[str, float]
    noise_std: float

    @property
    def signal_noise_std(self) -> float:
        """The ``noise_std`` as the signal's [1] near balance in clear sky: noise_std / tan(fov), the slope
        d signal / d e at e = 0 without diffuse light (diffuse light makes it smaller)."""
        return self.noise_std / math.tan(self.parameters["fov"])


def shipped_sun_sensors_path() -> Path:
    """The shipped presets, ``heliostep/data/sun_sensors.yaml``."""
    return Path(__file__).resolve().parents[1] / "data" / "sun_sensors.yaml"


def load_sun_sensors(path: str | Path | None = None) -> dict[str, SunSensorPreset]:
    """Every preset of the file (default: the shipped one) by name, every value checked.

    Raises
    ------
    InputError
        The file cannot be read, has no ``sun_sensors`` mapping, or a preset misses a key or has a bad
        value: naming the file and the dotted key.
    """
    source = Path(path) if path is not None else shipped_sun_sensors_path()
    try:
        stamp = source.stat()
    except OSError:  # read_yaml_file says what is wrong, naming the file
        return _read_presets(source, (0, 0))
    return dict(_read_presets(source, (stamp.st_mtime_ns, stamp.st_size)))


@functools.lru_cache(maxsize=8)
def _read_presets(source: Path, stamp: tuple[int, int]) -> dict[str, SunSensorPreset]:
    """The presets of ``source`` as it is at ``stamp`` (modified [ns], size [B]): read once per version."""
    document = read_yaml_file(source, "sun sensor presets")
    presets = document.get("sun_sensors") if isinstance(document, Mapping) else None
    if not isinstance(presets, Mapping) or not presets:
        raise InputError(f"{source}: sun_sensors: expected a mapping of preset name -> parameters")
    return {str(name): _preset(source, str(name), entry) for name, entry in presets.items()}


def sun_sensor(name: str, path: str | Path | None = None) -> SunSensorPreset:
    """Preset ``name`` of the file (default: the shipped one); InputError naming the presets when there is none."""
    source = Path(path) if path is not None else shipped_sun_sensors_path()
    presets = load_sun_sensors(source)
    if name not in presets:
        near = close_names(name, list(presets))
        hint = f" (close: {', '.join(near)})" if near else ""
        raise InputError(f"{source}: unknown sun sensor {name!r}{hint}; the presets are: {', '.join(presets)}")
    return presets[name]


def _preset(source: Path, name: str, entry) -> SunSensorPreset:
    """One preset checked: every key present and none other, texts non-empty, numbers finite and in range."""
    where = f"{source}: sun_sensors.{name}"
    if not isinstance(entry, Mapping):
        raise InputError(f"{where}: expected a mapping of {', '.join(_KEYS)}")
    missing = [key for key in _KEYS if entry.get(key) is None]
    if missing:
        raise InputError(f"{where}.{missing[0]}: missing (every preset needs {', '.join(_KEYS)})")
    extra = sorted(set(map(str, entry)) - set(_KEYS))
    if extra:
        raise InputError(f"{where}.{extra[0]}: unknown key; expected {', '.join(_KEYS)}")
    for key in _TEXT_KEYS:
        if not isinstance(entry[key], str) or not entry[key].strip():
            raise InputError(f"{where}.{key}: expected a non-empty text, got {entry[key]!r}")
    numbers = {
        key: _number(f"{where}.{key}", entry[key], unit) for key, unit in {**PARAMETER_KEYS, "noise_std": "rad"}.items()
    }
    bounds = {
        "k_ray": (numbers["k_ray"] > 0, "> 0"),
        "fov": (0 < numbers["fov"] < math.pi / 2, "between 0 and pi/2"),
        "threshold": (numbers["threshold"] >= 0, ">= 0"),
        "diffuse_view": (numbers["diffuse_view"] >= 0, ">= 0"),
        "noise_std": (numbers["noise_std"] >= 0, ">= 0"),
    }
    for key, (good, expected) in bounds.items():
        if not good:
            unit = PARAMETER_KEYS.get(key, "rad")
            raise InputError(f"{where}.{key}: expected {expected} [{unit}], got {entry[key]!r}")
    return SunSensorPreset(
        name=name,
        maker=entry["maker"],
        document=entry["document"],
        parameters={key: numbers[key] for key in PARAMETER_KEYS},
        noise_std=numbers["noise_std"],
    )


def _number(where: str, value, unit: str) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise InputError(f"{where}: expected a number [{unit}], got {value!r}")
    return float(value)
