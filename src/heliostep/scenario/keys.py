"""Dotted key paths: naming a place in a scenario (``window.start``) and setting one (``--set``)."""

from __future__ import annotations

from collections.abc import Sequence

import yaml

from heliostep.errors import InputError
from heliostep.scenario.yaml_io import parse_yaml_value, yaml_problem


class KeyProblems(ValueError):
    """Problems found by a validator, each with its key path relative to the model validated."""

    def __init__(self, problems: Sequence[tuple[tuple, str]]):
        self.problems = list(problems)
        super().__init__("; ".join(f"{dotted(path)}: {message}" for path, message in self.problems))


def dotted(loc: Sequence) -> str:
    text = ""
    for part in loc:
        if isinstance(part, int):
            text += f"[{part}]"
        else:
            text += f".{part}" if text else str(part)
    return text


def apply_overrides(data: dict, overrides: Sequence[str], source: str) -> dict:
    """Set ``"dotted.key=value"`` overrides in ``data`` (in place); values are YAML."""
    for override in overrides:
        shown = _shown(override)
        if not isinstance(override, str):
            raise InputError(f"{source}: --set {shown}: expected a string 'dotted.key=value'")
        key, equals, text = override.partition("=")
        parts = key.strip().split(".")
        if not equals or not all(part.strip() for part in parts):
            raise InputError(f"{source}: --set {shown}: expected 'dotted.key=value', e.g. 'sequencer.current=3'")
        parts = [part.strip() for part in parts]
        try:
            value = parse_yaml_value(text)
        except yaml.YAMLError as exc:
            raise InputError(f"{source}: --set {shown}: the value is not valid YAML: {yaml_problem(exc)}") from None
        set_dotted_key(data, parts, value, f"{source}: --set {shown}")
    return data


#: The most characters of an override a message repeats (a value can be megabytes long).
SHOWN_CHARACTERS = 80


def _shown(override) -> str:
    """``override`` as a message shows it: its repr, cut to :data:`SHOWN_CHARACTERS` with its length said."""
    text = repr(override)
    if len(text) <= SHOWN_CHARACTERS:
        return text
    return f"{text[:SHOWN_CHARACTERS]}... ({len(text):,} characters)"


def set_dotted_key(data: dict, parts: Sequence[str], value, where: str) -> None:
    """Set ``data[parts[0]][parts[1]]... = value``, creating missing mappings on the way.

    A part that is already something other than a mapping is an :class:`InputError`
    starting with ``where``.
    """
    node = data
    for depth, part in enumerate(parts[:-1]):
        child = node.get(part)
        if child is None:
            child = node[part] = {}
        elif not isinstance(child, dict):
            raise InputError(
                f"{where}: {'.'.join(parts[: depth + 1])} is {child!r}, not a mapping, "
                f"so it has no key {parts[depth + 1]!r}"
            )
        node = child
    node[parts[-1]] = value
