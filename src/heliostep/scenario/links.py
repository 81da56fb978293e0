"""A scenario's ``connections`` and ``transformations``: the pairs' form, the defaults, and their problems."""

from __future__ import annotations

import re
from collections.abc import Mapping, Sequence

from pydantic import Field

from heliostep.scenario.sections import Real, Section

#: Connections used when a scenario gives no ``connections``: (source, target).
DEFAULT_CONNECTIONS = [
    ("motor.tau", "mechanics.tau"),
    ("mechanics.theta", "motor.theta"),
    ("mechanics.omega", "motor.omega"),
]
INSTANCE_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")


class LinearTransformation(Section):
    """A connection's value as its target input gets it: ``factor * source + offset`` (SSP 1.0's
    ``ssc:LinearTransformation``, with any unit conversion folded in); its ends' units may differ."""

    factor: Real = Field(1.0, allow_inf_nan=False, description="multiplies the source's value")
    offset: Real = Field(0.0, allow_inf_nan=False, description="added after (in the target's unit)")


def connection_pair(value):
    if isinstance(value, (list, tuple)) and len(value) == 2 and all(isinstance(v, str) for v in value):
        return tuple(value)
    raise ValueError(f"expected a [source, target] pair of 'instance.variable' strings, got {value!r}")


def endpoint_problem(endpoint: str) -> str | None:
    instance, dot, variable = endpoint.partition(".")
    if not dot or not variable or not INSTANCE_NAME.fullmatch(instance):
        return f"expected 'instance.variable' (e.g. 'motor.tau'), got {endpoint!r}"
    return None


def connection_problems(
    connections: Sequence[tuple[str, str]] | None, fmus: Mapping, transformations: Mapping, instances: str
) -> list:
    """``connections`` (None: the default ones) naming an instance not in ``fmus``, or driving an input twice;
    ``transformations`` of inputs no connection drives."""
    problems: list[tuple[tuple, str]] = []
    if connections is None:
        missing = sorted({endpoint.partition(".")[0] for pair in DEFAULT_CONNECTIONS for endpoint in pair} - set(fmus))
        if missing:
            problems.append(
                (
                    ("connections",),
                    f"the default connections use FMU instance(s) "
                    f"{', '.join(missing)}, not in fmus ({instances}); "
                    f"give 'connections' explicitly ([] for none)",
                )
            )
    else:
        targets: dict[str, int] = {}
        for position, (source, target) in enumerate(connections):
            for side, endpoint in enumerate((source, target)):
                instance = endpoint.partition(".")[0]
                if instance not in fmus:
                    problems.append(
                        (
                            ("connections", position, side),
                            f"{endpoint!r}: unknown FMU instance {instance!r}; instances in fmus: {instances}",
                        )
                    )
            if target in targets:
                problems.append(
                    (
                        ("connections", position),
                        f"{target!r} is already the target of connections[{targets[target]}]; an input has one source",
                    )
                )
            targets.setdefault(target, position)
    driven = {target for _, target in (DEFAULT_CONNECTIONS if connections is None else connections)}
    for target in transformations:
        if target not in driven:
            problems.append((("transformations", target), "no connection drives this input; expected a target of one"))
    return problems
