"""Reading YAML the way heliostep means it: YAML 1.2 numbers, clock times as strings, no repeated keys.

Used for scenarios, sweeps, tolerance files and ``--set`` values: one reader for all.
"""

from __future__ import annotations

import re
from pathlib import Path

import yaml

from heliostep.errors import InputError


class HeliostepLoader(yaml.SafeLoader):
    """PyYAML's safe loader with YAML 1.2 numbers and an error on repeated keys."""

    def construct_mapping(self, node, deep=False):
        if isinstance(node, yaml.MappingNode):
            seen = set()
            for key_node, _ in node.value:
                if key_node.tag == "tag:yaml.org,2002:merge":
                    continue
                key = self.construct_object(key_node, deep=deep)
                try:
                    repeated = key in seen
                except TypeError:  # unhashable key: the base class reports it
                    continue
                if repeated:
                    raise yaml.constructor.ConstructorError(
                        "while constructing a mapping",
                        node.start_mark,
                        f"found the key {key!r} twice",
                        key_node.start_mark,
                    )
                seen.add(key)
        return super().construct_mapping(node, deep=deep)


_NUMBER_TAGS = ("tag:yaml.org,2002:int", "tag:yaml.org,2002:float")
HeliostepLoader.yaml_implicit_resolvers = {
    first: [(tag, regexp) for tag, regexp in resolvers if tag not in _NUMBER_TAGS]
    for first, resolvers in yaml.SafeLoader.yaml_implicit_resolvers.items()
}
HeliostepLoader.add_implicit_resolver(
    "tag:yaml.org,2002:int",
    re.compile(r"^(?:[-+]?(?:0|[1-9][0-9_]*)|0x[0-9a-fA-F_]+|0o[0-7_]+)$"),
    list("-+0123456789"),
)
HeliostepLoader.add_implicit_resolver(
    "tag:yaml.org,2002:float",
    re.compile(
        r"""^(?:[-+]?(?:[0-9][0-9_]*\.[0-9_]*(?:[eE][-+]?[0-9]+)?
                |\.[0-9_]+(?:[eE][-+]?[0-9]+)?
                |[0-9][0-9_]*[eE][-+]?[0-9]+)
            |[-+]?\.(?:inf|Inf|INF)
            |\.(?:nan|NaN|NAN))$""",
        re.X,
    ),
    list("-+0123456789."),
)


def _octal_aware_int(loader, node):
    value = loader.construct_scalar(node).replace("_", "")
    if value.startswith("0o"):
        return int(value[2:], 8)
    return int(value, 0) if value.startswith("0x") else int(value)


HeliostepLoader.add_constructor("tag:yaml.org,2002:int", _octal_aware_int)


def yaml_problem(exc: yaml.YAMLError) -> str:
    mark = getattr(exc, "problem_mark", None)
    problem = getattr(exc, "problem", None) or str(exc)
    if mark is None:
        return problem
    return f"line {mark.line + 1}, column {mark.column + 1}: {problem}"


def parse_yaml_value(text: str):
    """One YAML value (a ``--set`` right-hand side) read like the files; :class:`yaml.YAMLError` on bad YAML."""
    return yaml.load(text, Loader=HeliostepLoader)  # noqa: S506 - a SafeLoader


def read_yaml_file(path: str | Path, what: str):
    """Read a YAML file the way heliostep reads scenarios (and sweeps).

    YAML 1.2 numbers (``1e-6`` is a float), clock times such as ``10:00`` kept as strings,
    a key repeated in one mapping refused. Every problem is an :class:`InputError` naming
    the file (``what`` says which kind of file it is).
    """
    source = str(path)
    try:
        text = Path(path).read_text(encoding="utf-8")
    except FileNotFoundError:
        raise InputError(f"{source}: {what} file not found") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"{source}: cannot read the {what} file: {exc}") from None
    try:
        return yaml.load(text, Loader=HeliostepLoader)  # noqa: S506 - a SafeLoader
    except yaml.YAMLError as exc:
        raise InputError(f"{source}: not valid YAML: {yaml_problem(exc)}") from None
