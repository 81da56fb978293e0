"""Tolerances of a trace comparison: per signal an absolute, a relative and a time tolerance.

:class:`Tolerance` is one signal's; :class:`ToleranceSet` a default with per-signal (and per-scenario)
overrides; :func:`load_tolerances` reads them from YAML. The tube they define:
:mod:`heliostep.results.compare.tube`; the comparison: :mod:`heliostep.results.compare.traces`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from types import MappingProxyType
from typing import cast

import numpy as np

from heliostep.errors import InputError
from heliostep.scenario import read_yaml_file

__all__ = ["Tolerance", "ToleranceSet", "as_tolerance_set", "load_tolerances"]

_TOL_KEYS = ("abs", "rel", "time")


def _non_negative(value: object, what: str) -> float:
    if isinstance(value, bool):
        raise InputError(f"{what}: expected a non-negative number, got {value!r}")
    try:
        number = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        raise InputError(f"{what}: expected a non-negative number, got {value!r}") from None
    if not math.isfinite(number) or number < 0:
        raise InputError(f"{what}: expected a non-negative number, got {value!r}")
    return number


@dataclass(frozen=True)
class Tolerance:
    """Tolerance of one signal: absolute (signal units), relative (-), time (s)."""

    abs: float = 1e-6
    rel: float = 1e-4
    time: float = 1e-3

    def __post_init__(self) -> None:
        for name in _TOL_KEYS:
            object.__setattr__(self, name, _non_negative(getattr(self, name), f"tolerance {name!r}"))

    def half_width(self, values: np.ndarray) -> np.ndarray:
        """Half-width of the value band around reference *values*: ``max(abs, rel*|y|)``."""
        return np.maximum(self.abs, self.rel * np.abs(values))


@dataclass(frozen=True)
class ToleranceSet:
    """A default :class:`Tolerance` and per-signal overrides of some of its fields.

    ``signals`` maps a signal name to a mapping with some of the keys ``abs``,
    ``rel``, ``time``; the fields it does not give come from ``default``.
    """

    default: Tolerance = field(default_factory=Tolerance)
    signals: Mapping[str, Mapping[str, float]] = field(default_factory=dict)
    #: per scenario name, signal overrides that apply to that scenario only (:meth:`for_scenario`)
    scenarios: Mapping[str, Mapping[str, Mapping[str, float]]] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if not isinstance(self.default, Tolerance):
            raise InputError(f"default tolerance must be a Tolerance, not {type(self.default).__name__}")
        frozen = {}
        for name, override in self.signals.items():
            if isinstance(override, Tolerance):
                override = {k: getattr(override, k) for k in _TOL_KEYS}
            if not isinstance(override, Mapping):
                raise InputError(f"tolerance of signal {name!r} must be a mapping")
            checked = {}
            for key, value in override.items():
                if key not in _TOL_KEYS:
                    raise InputError(
                        f"tolerance of signal {name!r}: unknown key {key!r} (expected {', '.join(_TOL_KEYS)})"
                    )
                checked[key] = _non_negative(value, f"tolerance {key!r} of signal {name!r}")
            frozen[str(name)] = MappingProxyType(checked)
        object.__setattr__(self, "signals", MappingProxyType(frozen))

    def for_signal(self, name: str) -> Tolerance:
        """The tolerance that applies to signal *name*."""
        return replace(self.default, **self.signals.get(name, {}))

    def for_scenario(self, name: str) -> ToleranceSet:
        """The tolerances that apply to scenario *name*: its own section's signals over these."""
        own = self.scenarios.get(name, {})
        merged = {signal: {**self.signals.get(signal, {}), **own.get(signal, {})} for signal in {*self.signals, *own}}
        return ToleranceSet(self.default, merged)

    def with_default(self, **changes: float) -> ToleranceSet:
        """A copy whose default has the given fields (``abs``, ``rel``, ``time``) replaced."""
        return ToleranceSet(replace(self.default, **changes), self.signals)


def load_tolerances(path: str | Path) -> ToleranceSet:
    """Read a YAML tolerance file.

    Format (both sections optional; numbers may be written ``1e-6``)::

        default: {abs: 1e-6, rel: 1e-4, time: 1e-3}
        signals:
          motor.tau: {abs: 1e-3}
        scenarios:            # optional: overrides for one scenario (by its name)
          jan21-weak-motor:
            signals:
              motor.tau: {abs: 1e-1}

    Fields missing from ``default`` keep the built-in defaults of :class:`Tolerance`.
    Unknown keys, non-numbers and negative numbers raise
    :class:`~heliostep.errors.InputError` naming the file and the key.
    """
    path = Path(path)
    data = read_yaml_file(path, "tolerance")  # heliostep's one YAML reader: a repeated key is an error
    if data is None:
        data = {}
    if not isinstance(data, Mapping):
        raise InputError(f"{path}: expected a mapping with keys 'default' and 'signals'")

    def section(value: object, where: str) -> dict[str, float]:
        if value is None:
            return {}
        if not isinstance(value, Mapping):
            raise InputError(f"{path}: {where}: expected a mapping of {', '.join(_TOL_KEYS)}")
        out = {}
        for key, number in value.items():
            if key not in _TOL_KEYS:
                raise InputError(f"{path}: unknown key {key!r} in {where} (expected {', '.join(_TOL_KEYS)})")
            try:
                out[key] = _non_negative(number, f"{where}.{key}")
            except InputError as exc:
                raise InputError(f"{path}: {exc}") from None
        return out

    def signal_sections(value: object, where: str) -> dict[str, dict[str, float]]:
        if value is None:
            return {}
        if not isinstance(value, Mapping):
            raise InputError(f"{path}: '{where}' must map signal names to tolerances")
        return {str(name): section(entry, f"{where}.{name}") for name, entry in value.items()}

    for key in data:
        if key not in ("default", "signals", "scenarios"):
            raise InputError(f"{path}: unknown key {key!r} (expected 'default', 'signals', 'scenarios')")
    default = Tolerance(**section(data.get("default"), "default"))
    signals = signal_sections(data.get("signals"), "signals")
    raw_scenarios = data.get("scenarios") or {}
    if not isinstance(raw_scenarios, Mapping):
        raise InputError(f"{path}: 'scenarios' must map scenario names to {{signals: ...}}")
    scenarios = {}
    for name, entry in raw_scenarios.items():
        if not isinstance(entry, Mapping) or set(entry) - {"signals"}:
            raise InputError(f"{path}: scenarios.{name}: expected a mapping with the key 'signals'")
        scenarios[str(name)] = signal_sections(entry.get("signals"), f"scenarios.{name}.signals")
    return ToleranceSet(default, signals, scenarios)


def as_tolerance_set(tolerances: Tolerance | ToleranceSet | Mapping[str, Tolerance] | None) -> ToleranceSet:
    """*tolerances* as a :class:`ToleranceSet`: a set as it is, one :class:`Tolerance` as its default, a mapping
    signal -> :class:`Tolerance` as overrides of the built-in default, None as the built-in default."""
    if tolerances is None:
        return ToleranceSet()
    if isinstance(tolerances, ToleranceSet):
        return tolerances
    if isinstance(tolerances, Tolerance):
        return ToleranceSet(tolerances)
    if isinstance(tolerances, Mapping):
        # ToleranceSet turns Tolerance values into mappings of their fields
        return ToleranceSet(Tolerance(), cast("dict[str, Mapping[str, float]]", dict(tolerances)))
    raise InputError(f"tolerances: expected a Tolerance or ToleranceSet, not {type(tolerances).__name__}")
