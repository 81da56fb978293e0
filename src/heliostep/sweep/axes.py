"""The axes of a sweep: shorthand names, the values an axis expands to and the scenario
settings one value makes (the cases they combine into: :mod:`heliostep.sweep.spec`)."""

from __future__ import annotations

import dataclasses
import datetime as dt
import json
import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from heliostep.errors import InputError
from heliostep.scenario import Scenario, parse_yaml_value
from heliostep.scenario.catalogue import load_catalogue, motor_overrides
from heliostep.solar import N_FIELD_MIRRORS

__all__ = [
    "CATALOGUE_AXIS",
    "CENTRAL_MIRROR",
    "SHORTHAND_AXES",
    "SweepAxis",
    "check_case_count",
    "count_cases",
    "axis_hint",
    "axis_values",
    "catalogue_path",
    "check_axis_key",
    "make_axis",
    "setting_by_role",
    "show_value",
    "table_value",
]

#: Shorthand axis name -> the dotted scenario key it sets (day_of_year and mirror are special).
SHORTHAND_AXES = {
    "day_of_year": "window.date",
    "mirror": "mirror.index",
    "motor": "fmus.motor",
    "mechanics": "fmus.mechanics",
    "current": "sequencer.current",
    "wind_moment": "wind.moment",
}


#: Table column of each shorthand axis (a column the table always has).
_SHORTHAND_COLUMNS = {
    "day_of_year": "day_of_year",
    "mirror": "mirror_index",
    "motor": "motor",
    "mechanics": "mechanics",
    "current": "current_A",
    "wind_moment": "wind_moment_Nm",
}


#: The axis whose values are motor catalogue entries by name: each sets what ``heliostep run --motor`` sets.
CATALOGUE_AXIS = "catalogue_motor"


#: Index of the central mirror of the field (distance 0), whose law the shared primary follows.
CENTRAL_MIRROR = N_FIELD_MIRRORS // 2


#: The role whose FMU instance the shorthand axes ``motor`` and ``mechanics`` swap.
_SHORTHAND_ROLES = {"motor": "torque", "mechanics": "panel_angle"}


def setting_by_role(setting: tuple[str, Any], axis: str, base: Mapping) -> tuple[str, Any]:
    """``fmus.motor`` of the shorthand axes ``motor`` / ``mechanics`` as the instance that plays
    the motor's (torque) or the mechanics' (panel angle) role in the base scenario."""
    role = _SHORTHAND_ROLES.get(axis)
    target = (base.get("roles") or {}).get(role) if role else None
    if not target:
        return setting
    return (f"fmus.{target.partition('.')[0]}", setting[1])


@dataclasses.dataclass(frozen=True)
class SweepAxis:
    """One axis of a sweep.

    Attributes
    ----------
    name : str
        As written in the sweep: a shorthand of :data:`SHORTHAND_AXES` or a dotted key.
    values : tuple
        The expanded values ("all" and ranges resolved), in order.
    settings : tuple
        (value, its (dotted key, value) settings) pairs, for an axis whose settings are worked out
        beforehand (:data:`CATALOGUE_AXIS`); empty otherwise.
    """

    name: str
    values: tuple
    settings: tuple = ()

    @property
    def column(self) -> str:
        """The results-table column holding this axis's value."""
        return _SHORTHAND_COLUMNS.get(self.name, self.name)

    def overrides(self, value, year: int) -> tuple[tuple[str, Any], ...]:
        """The (dotted key, value) settings for one value of this axis.

        Parameters
        ----------
        value
            One of :attr:`values`.
        year : int
            Year of the base scenario's window (for ``day_of_year``).
        """
        if self.settings:
            return dict(self.settings)[value]
        if self.name == "day_of_year":
            return (("window.date", _date_of_day(year, value)),)
        if self.name == "mirror":
            return (("mirror.distance", None), ("mirror.index", value))
        return ((SHORTHAND_AXES.get(self.name, self.name), value),)


def make_axis(name, raw, year: int, where: str, base: Scenario, catalogue: Path | None) -> SweepAxis:
    """One axis of the sweep, checked; ``base`` (the base scenario with the sweep's overrides) and ``catalogue``
    (None: the shipped one) give :data:`CATALOGUE_AXIS`'s settings."""
    name = check_axis_key(name, where)
    values = axis_values(name, raw, year, f"{where}.{name}")
    if name != CATALOGUE_AXIS:
        return SweepAxis(name=name, values=values)
    return SweepAxis(name=name, values=values, settings=_catalogue_settings(values, base, catalogue, f"{where}.{name}"))


def _catalogue_settings(names: tuple, base: Scenario, catalogue: Path | None, where: str) -> tuple:
    """Each catalogue motor's settings on ``base``: the ``--set`` items ``heliostep run --motor`` applies
    (:func:`~heliostep.scenario.catalogue.motor_overrides`), read as ``--set`` reads them."""
    for name in names:
        if not isinstance(name, str):
            raise InputError(f"{where}: {name!r}: expected a motor catalogue name (heliostep motors lists them)")
    try:
        candidates = load_catalogue(catalogue, names)  # unknown names refused with the close ones
    except InputError as exc:
        raise InputError(f"{where}: {exc}") from None
    pairs = [(c.name, [item.partition("=") for item in motor_overrides(base, c)]) for c in candidates]
    return tuple((name, tuple((key, parse_yaml_value(text)) for key, _, text in items)) for name, items in pairs)


def catalogue_path(sweep: Mapping, sweep_file: Path, where: str) -> Path | None:
    """The sweep file's ``catalogue`` (relative to the sweep file) for its :data:`CATALOGUE_AXIS`, or None (the
    shipped catalogue); refused without that axis."""
    raw = sweep.get("catalogue")
    if raw is None:
        return None
    if not isinstance(raw, str) or not raw.strip():
        raise InputError(f"{where}: expected the path of a motor catalogue (relative to the sweep file), got {raw!r}")
    axes = sweep.get("axes")
    if not isinstance(axes, Mapping) or CATALOGUE_AXIS not in axes:
        raise InputError(f"{where}: a catalogue is for the {CATALOGUE_AXIS} axis, which the sweep does not have")
    path = Path(raw).expanduser()
    return path if path.is_absolute() else sweep_file.absolute().parent / path


def check_axis_key(key, where: str) -> str:
    if not isinstance(key, str) or not all(part.strip() for part in key.split(".")) or key != key.strip():
        raise InputError(
            f"{where}: {key!r}: expected a shorthand ({', '.join([*SHORTHAND_AXES, CATALOGUE_AXIS])}) or a "
            f"dotted scenario key such as 'sequencer.current'"
        )
    return key


def axis_hint(name: str) -> str:
    if name == "mirror.index":
        return " (to sweep the field's mirrors use the 'mirror' axis, which also clears mirror.distance)"
    if name == "window.date":
        return " (or use the 'day_of_year' axis)"
    return ""


def axis_values(name: str, raw, year: int, where: str) -> tuple:
    """Expand one axis's values: a list, "all" (day_of_year, mirror) or {start, stop, step}."""
    if isinstance(raw, str) and raw.strip().lower() == "all":
        if name == "mirror":
            return tuple(range(N_FIELD_MIRRORS))
        if name == "day_of_year":
            return tuple(range(1, _days_in_year(year) + 1))
        raise InputError(f"{where}: 'all' is only for the day_of_year and mirror axes")
    if isinstance(raw, Mapping):
        values = _range_values(raw, where)
    elif isinstance(raw, (list, tuple)):
        values = tuple(raw)
    else:
        raise InputError(
            f"{where}: expected a list of values, 'all' (day_of_year, mirror) or {{start, stop, step}}, got {raw!r}"
        )
    if not values:
        raise InputError(f"{where}: the axis is empty; give at least one value")
    seen = set()
    for value in values:
        if show_value(value) in seen:
            raise InputError(f"{where}: the value {value!r} is repeated")
        seen.add(show_value(value))
    if name == "day_of_year":
        days = _days_in_year(year)
        for value in values:
            if isinstance(value, bool) or not isinstance(value, int) or not 1 <= value <= days:
                raise InputError(
                    f"{where}: {value!r}: expected a day of year, an integer from 1 to {days} "
                    f"(the base scenario's year is {year})"
                )
    if name == "mirror":
        for value in values:
            if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value < N_FIELD_MIRRORS:
                raise InputError(
                    f"{where}: {value!r}: expected a mirror index, an integer from 0 to "
                    f"{N_FIELD_MIRRORS - 1} ({CENTRAL_MIRROR} is the central mirror), or 'all'"
                )
    return values


def count_cases(axes, combine: str, shared_primary: bool) -> int:
    """Cases of a sweep of ``axes`` combined by ``combine`` ("product" or "zip"), the shared
    primary's (one per combination of the axes but ``mirror``) included, counted, not built."""
    lengths = [len(axis.values) for axis in axes]
    drives = min(lengths) if combine == "zip" else math.prod(lengths)
    if shared_primary:
        others = [len(axis.values) for axis in axes if axis.name != "mirror"]
        drives += min(others, default=1) if combine == "zip" else math.prod(others)
    return drives


def check_case_count(source: str, axes, combine: str, shared_primary: bool, max_cases: int) -> None:
    """Refuse (InputError) a sweep of more than ``max_cases`` cases, naming its axes and the count."""
    count = count_cases(axes, combine, shared_primary)
    if count > max_cases:
        joined = f" {'x' if combine == 'product' else 'zip'} ".join(f"{a.name} ({len(a.values)} values)" for a in axes)
        raise InputError(
            f"{source}: axes: {joined} make {count:,} cases, over max_cases = {max_cases:,}; "
            "each case is a run: fewer values, or max_cases in the sweep file if meant"
        )


#: The most values a range axis may expand to (counted before any is made; the sweep's cases are
#: bounded by its ``max_cases`` besides).
MAX_AXIS_VALUES = 1_000_000


def _range_values(raw: Mapping, where: str) -> tuple:
    if set(raw) - {"start", "stop", "step"} or not {"start", "stop"} <= set(raw):
        raise InputError(f"{where}: a range is {{start, stop, step}} (step optional, default 1), got {dict(raw)!r}")
    start, stop, step = raw["start"], raw["stop"], raw.get("step", 1)
    for key, value in (("start", start), ("stop", stop), ("step", step)):
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            raise InputError(f"{where}.{key}: expected a number, got {value!r}")
    if step <= 0:
        raise InputError(f"{where}.step: expected a number > 0, got {step!r}")
    if stop < start:
        raise InputError(f"{where}: stop ({stop}) is before start ({start})")
    count = math.floor((stop - start) / step + 1e-9) + 1
    if count > MAX_AXIS_VALUES:
        raise InputError(f"{where}: a range of {count:.3g} values; expected at most {MAX_AXIS_VALUES:,}")
    if all(isinstance(v, int) for v in (start, stop, step)):
        return tuple(start + k * step for k in range(count))
    return tuple(float(np.round(start + k * step, 12)) for k in range(count))


def _days_in_year(year: int) -> int:
    return 366 if (year % 4 == 0 and year % 100 != 0) or year % 400 == 0 else 365


def _date_of_day(year: int, day_of_year: int) -> dt.date:
    return dt.date(year, 1, 1) + dt.timedelta(days=day_of_year - 1)


def show_value(value) -> str:
    if isinstance(value, (dt.date, dt.time)):
        return value.isoformat()
    return json.dumps(value, default=str)


def table_value(value):
    """An axis value as a table cell: scalars as they are, dates as ISO text, the rest as JSON."""
    if value is None or isinstance(value, (bool, int, float, str)):
        return value
    return show_value(value)
