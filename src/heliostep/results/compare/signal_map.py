"""Which signal of an actual trace is compared with which signal of a reference trace: explicit,
by role, or by name.

Details: docs/compare.md, ``heliostep.results.compare.signal_map``.
"""

from __future__ import annotations

import csv
import io
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

from heliostep.errors import InputError
from heliostep.input_files import MAX_YAML_BYTES, read_input_text
from heliostep.results.trace.format import TIME

__all__ = [
    "MatchKind",
    "SignalMatch",
    "load_signal_map",
    "match_signals",
    "parse_map_options",
    "roles_of",
    "signal_units",
]

#: How a reference signal found its actual column.
MatchKind = Literal["explicit", "role", "name"]

_ROLE_PREFIX = "role."


@dataclass(frozen=True)
class SignalMatch:
    """A reference signal and the actual column compared with it; *role* when matched by role."""

    reference: str
    actual: str
    how: MatchKind
    role: str | None = None

    def describe(self) -> str:
        """E.g. ``drive.tauMot -> motor.tau (by role torque)``."""
        how = f"role {self.role}" if self.how == "role" else self.how
        return f"{self.actual} -> {self.reference} (by {how})"


def roles_of(metadata: Mapping[str, str] | None) -> dict[str, str]:
    """The roles a trace's metadata names: role -> column (from the ``role.<role>`` keys)."""
    return {
        key[len(_ROLE_PREFIX) :]: str(value)
        for key, value in (metadata or {}).items()
        if key.startswith(_ROLE_PREFIX) and key[len(_ROLE_PREFIX) :]
    }


def parse_map_options(values: Iterable[str] | None, where: str = "--map") -> dict[str, str]:
    """``["actual=reference", ...]`` as a mapping actual -> reference; InputError for a bad entry."""
    out: dict[str, str] = {}
    for value in values or ():
        actual, sep, reference = (part.strip() for part in str(value).partition("="))
        if not sep or not actual or not reference:
            raise InputError(f"{where}: expected ACTUAL=REFERENCE, got {value!r}")
        _add(out, actual, reference, where)
    return out


def _add(out: dict[str, str], actual: str, reference: str, where: str) -> None:
    if actual in out:
        raise InputError(f"{where}: actual signal {actual!r} mapped twice ({out[actual]!r} and {reference!r})")
    if reference in out.values():
        raise InputError(f"{where}: reference signal {reference!r} is the target of two actual signals")
    out[actual] = reference


def load_signal_map(path: str | Path) -> dict[str, str]:
    """A mapping file as actual -> reference.

    YAML (``.yaml``/``.yml``): a mapping ``ACTUAL: REFERENCE``. CSV (any other suffix): a header
    line ``actual,reference`` (in either order), then one pair per line. InputError naming the
    file and the line or key for anything else.
    """
    path = Path(path)
    if not path.exists():
        raise InputError(f"{path}: no such file (signal mapping)")
    if path.suffix.lower() in (".yaml", ".yml"):
        from heliostep.scenario import read_yaml_file

        data = read_yaml_file(path, "signal mapping")
        if not isinstance(data, Mapping) or not data:
            raise InputError(f"{path}: expected a mapping 'ACTUAL: REFERENCE' of signal names")
        out: dict[str, str] = {}
        for actual, reference in data.items():
            if not isinstance(actual, str) or not isinstance(reference, str) or not actual or not reference:
                raise InputError(f"{path}: entry {actual!r}: expected 'ACTUAL: REFERENCE' with two signal names")
            _add(out, actual.strip(), reference.strip(), str(path))
        return out
    return _read_map_csv(path)


def _read_map_csv(path: Path) -> dict[str, str]:
    text = read_input_text(path, "signal mapping", MAX_YAML_BYTES, "utf-8-sig")
    try:
        rows = list(csv.reader(io.StringIO(text)))
    except csv.Error as exc:
        raise InputError(f"{path}: cannot read the signal mapping: {exc}") from None
    rows = [[cell.strip() for cell in row] for row in rows if any(cell.strip() for cell in row)]
    if not rows or sorted(c.lower() for c in rows[0]) != ["actual", "reference"]:
        raise InputError(f"{path}: line 1: expected the header 'actual,reference'")
    a, r = [c.lower() for c in rows[0]].index("actual"), [c.lower() for c in rows[0]].index("reference")
    out: dict[str, str] = {}
    for number, row in enumerate(rows[1:], start=2):
        if len(row) != 2 or not row[0] or not row[1]:
            raise InputError(f"{path}: line {number}: expected two signal names, got {row!r}")
        _add(out, row[a], row[r], f"{path}: line {number}")
    return out


def match_signals(
    actual_columns: Sequence[str],
    reference_columns: Sequence[str],
    actual_metadata: Mapping[str, str] | None = None,
    reference_metadata: Mapping[str, str] | None = None,
    explicit: Mapping[str, str] | None = None,
    *,
    actual_name: str = "actual",
    reference_name: str = "reference",
) -> dict[str, SignalMatch]:
    """The match of each reference signal that finds one, in the reference's column order.

    *explicit* maps actual -> reference names; each name must be a column of its trace
    (:class:`~heliostep.errors.InputError` otherwise). Reference signals without a match are
    simply absent from the result: the caller decides whether that is an error.
    """
    actual_set = [c for c in actual_columns if c != TIME]
    reference_set = [c for c in reference_columns if c != TIME]
    matches: dict[str, SignalMatch] = {}
    used: set[str] = set()
    for actual, reference in (explicit or {}).items():
        if actual not in actual_set:
            raise InputError(f"signal mapping {actual}={reference}: {actual_name} has no column {actual!r}")
        if reference not in reference_set:
            raise InputError(f"signal mapping {actual}={reference}: {reference_name} has no column {reference!r}")
        matches[reference] = SignalMatch(reference, actual, "explicit")
        used.add(actual)
    actual_roles = roles_of(actual_metadata)
    role_of_reference = {column: role for role, column in roles_of(reference_metadata).items()}
    for reference in reference_set:
        role = role_of_reference.get(reference)
        actual = actual_roles.get(role, "") if role else ""
        if reference in matches or actual not in actual_set or actual in used:
            continue
        how: MatchKind = "name" if actual == reference else "role"
        matches[reference] = SignalMatch(reference, actual, how, role if how == "role" else None)
        used.add(actual)
    for reference in reference_set:
        if reference not in matches and reference in actual_set and reference not in used:
            matches[reference] = SignalMatch(reference, reference, "name")
            used.add(reference)
    return {reference: matches[reference] for reference in reference_set if reference in matches}


def signal_units(
    matches: Mapping[str, SignalMatch],
    actual_metadata: Mapping[str, str] | None,
    reference_metadata: Mapping[str, str] | None,
) -> dict[str, str]:
    """Unit of each matched reference signal (and of ``time``): the reference's ``unit.<column>``,
    else the actual's for its matched column; signals with neither are absent."""
    actual_metadata, reference_metadata = actual_metadata or {}, reference_metadata or {}
    units = {}
    for reference, match in {TIME: SignalMatch(TIME, TIME, "name"), **matches}.items():
        unit = reference_metadata.get(f"unit.{reference}") or actual_metadata.get(f"unit.{match.actual}")
        if unit:
            units[reference] = unit
    return units
