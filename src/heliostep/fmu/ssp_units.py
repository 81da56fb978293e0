"""Units and linear maps of an SSP 1.0 system: a value converted between two units, and the affine maps
(``target = factor * source + offset``) that connections, unit conversions and mappings apply, composed.

A unit is defined by its SI base-unit exponents, ``factor`` and ``offset`` (SSP's ``ssc:Unit`` and FMI's
``UnitDefinitions`` alike: value in base units = factor * value + offset); two units convert into each
other when their exponents are equal.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from typing import Any

from heliostep.errors import InputError

#: The SI base units (and rad) a unit's exponents are given in.
BASE_UNITS = ("kg", "m", "s", "A", "K", "mol", "cd", "rad")
#: The identity map: no transformation.
IDENTITY = (1.0, 0.0)


def unit_definitions(*sources: Iterable[Any]) -> dict[str, Any]:
    """Unit name -> its definition (an object with the base-unit exponents, ``factor`` and ``offset``): the
    first source that defines a name wins (the SSP's own units before its FMUs')."""
    defined: dict[str, Any] = {}
    for units in sources:
        for unit in units:
            base = getattr(unit, "baseUnit", unit)  # an FMU's Unit holds a BaseUnit; an SSP's is flat
            if base is not None:
                defined.setdefault(unit.name, base)
    return defined


def conversion(source: str, target: str, defined: Mapping[str, Any], where: str) -> tuple[float, float]:
    """The map from a value in unit ``source`` to the same quantity in unit ``target``; InputError naming
    ``where`` when either unit is not defined or their dimensions differ."""
    if source == target:
        return IDENTITY
    missing = [name for name in (source, target) if name not in defined]
    if missing:
        raise InputError(
            f"{where}: units {source!r} and {target!r} differ and {missing[0]!r} has no definition"
            " (ssd:Units, or the FMU's UnitDefinitions) to convert them by"
        )
    a, b = defined[source], defined[target]
    exponents = [(getattr(a, k, 0) or 0, getattr(b, k, 0) or 0) for k in BASE_UNITS]
    if any(x != y for x, y in exponents):
        raise InputError(f"{where}: units {source!r} and {target!r} are of different quantities; no conversion")
    fa, oa = float(getattr(a, "factor", 1.0) or 1.0), float(getattr(a, "offset", 0.0) or 0.0)
    fb, ob = float(getattr(b, "factor", 1.0) or 1.0), float(getattr(b, "offset", 0.0) or 0.0)
    return (1.0, 0.0) if (fa, oa) == (fb, ob) else (fa / fb, (oa - ob) / fb)


def then(first: tuple[float, float], second: tuple[float, float]) -> tuple[float, float]:
    """``first`` applied, then ``second``: exact when either is the identity."""
    if first == IDENTITY:
        return second
    if second == IDENTITY:
        return first
    (a1, b1), (a2, b2) = first, second
    return a2 * a1, a2 * b1 + b2


def applied(transform: tuple[float, float], value: float) -> float:
    """``factor * value + offset`` (the value itself for the identity)."""
    factor, offset = transform
    return value if transform == IDENTITY else factor * value + offset
