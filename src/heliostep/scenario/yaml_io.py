"""Reading YAML the way heliostep means it: YAML 1.2 numbers, clock times as strings, no repeated keys.

Used for scenarios, sweeps, tolerance files and ``--set`` values: one reader for all. Bounded:
nesting deeper than :data:`MAX_DEPTH` levels (which would exhaust Python's recursion) and
documents whose aliases expand to more than :data:`MAX_EXPANDED_NODES` nodes (an alias bomb, that
would take minutes and gigabytes to walk) are refused as bad YAML, naming the line. A date that
does not exist (an unquoted ``2025-02-29``) is kept as its text, so the key's own check names it.
"""

from __future__ import annotations

import re
import sys
from pathlib import Path

import yaml

from heliostep.errors import InputError
from heliostep.input_files import MAX_YAML_BYTES, read_input_text

#: Deepest nesting of mappings and lists a file may have (a scenario has 4).
MAX_DEPTH = 64
#: Most nodes a document may have with its aliases expanded (a scenario has a few hundred).
MAX_EXPANDED_NODES = 200_000


def _expanded_size(node, sizes: dict[int, int]) -> int:
    """Nodes of ``node`` with every alias expanded (each shared node counted once per use)."""
    known = sizes.get(id(node))
    if known is not None:
        return known
    size = 1
    if isinstance(node, yaml.SequenceNode):
        size += sum(_expanded_size(item, sizes) for item in node.value)
    elif isinstance(node, yaml.MappingNode):
        size += sum(_expanded_size(key, sizes) + _expanded_size(value, sizes) for key, value in node.value)
    sizes[id(node)] = size = min(size, MAX_EXPANDED_NODES + 1)
    return size


class HeliostepLoader(yaml.SafeLoader):
    """PyYAML's safe loader with YAML 1.2 numbers, an error on repeated keys, and limits on
    nesting and alias expansion."""

    _depth = 0

    def compose_node(self, parent, index):
        self._depth += 1
        try:
            if self._depth > MAX_DEPTH:
                raise yaml.composer.ComposerError(
                    None, None, f"nested deeper than {MAX_DEPTH} levels", self.peek_event().start_mark
                )
            return super().compose_node(parent, index)
        finally:
            self._depth -= 1

    def get_single_node(self):
        node = super().get_single_node()
        if node is not None and _expanded_size(node, {}) > MAX_EXPANDED_NODES:
            raise yaml.composer.ComposerError(
                None, None, f"more than {MAX_EXPANDED_NODES} values with its aliases expanded", node.start_mark
            )
        return node

    def construct_yaml_timestamp(self, node):
        try:
            return super().construct_yaml_timestamp(node)
        except ValueError:  # e.g. 2025-02-29: the text, for the key's own check to name
            return self.construct_scalar(node)

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
    try:
        if value.startswith("0o"):
            return int(value[2:], 8)
        return int(value, 0) if value.startswith("0x") else int(value)
    except ValueError:  # more digits than Python converts (sys.get_int_max_str_digits)
        raise yaml.constructor.ConstructorError(
            None,
            None,
            f"an integer of {len(value)} digits; expected at most {sys.get_int_max_str_digits()}",
            node.start_mark,
        ) from None


HeliostepLoader.add_constructor("tag:yaml.org,2002:int", _octal_aware_int)
HeliostepLoader.add_constructor("tag:yaml.org,2002:timestamp", HeliostepLoader.construct_yaml_timestamp)


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
    a key repeated in one mapping refused. Only a regular file of at most
    :data:`~heliostep.input_files.MAX_YAML_BYTES` is read. Every problem is an :class:`InputError` naming
    the file (``what`` says which kind of file it is).
    """
    source = str(path)
    text = read_input_text(path, what, MAX_YAML_BYTES)
    try:
        return yaml.load(text, Loader=HeliostepLoader)  # noqa: S506 - a SafeLoader
    except yaml.YAMLError as exc:
        raise InputError(f"{source}: not valid YAML: {yaml_problem(exc)}") from None
