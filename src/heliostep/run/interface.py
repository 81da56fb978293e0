"""A helpful refusal for FMUs whose variables do not match the connections and roles, with a
``connections`` and ``roles`` block that would fit, ready to paste into the scenario.

Details: docs/running.md, ``heliostep.run.interface``.
"""

from __future__ import annotations

import difflib
import re

from heliostep.cosim import FMUInfo
from heliostep.errors import InputError
from heliostep.scenario import INPUT_ROLES, OUTPUT_ROLES, PARAMETER_ROLES, REQUIRED_ROLES, Scenario

__all__ = ["SHIPPED_UNITS", "check_interface", "propose_interface"]

#: The shipped interface's variables (``models/StepperMotor.mo``, ``models/PanelMechanics.mo``) and
#: their units: what a default connection or role expects of the variable it names.
SHIPPED_UNITS = {
    "i_a_ref": "A",
    "i_b_ref": "A",
    "theta": "rad",
    "omega": "rad/s",
    "tau": "N.m",
    "i_a": "A",
    "i_b": "A",
    "v_a": "V",
    "v_b": "V",
    "power": "W",
    "m_ext": "N.m",
    "theta_p": "rad",
    "omega_p": "rad/s",
    "theta_p_start": "rad",
    "theta_start": "rad",
    "r": "m",
    "s": "m",
    "i_a_start": "A",
    "i_b_start": "A",
}

_ROLE_CAUSALITY = {
    **{r: "input" for r in INPUT_ROLES},
    **{r: "output" for r in OUTPUT_ROLES},
    **{r: "parameter" for r in PARAMETER_ROLES},
}


def _exists(target: str, infos: dict[str, FMUInfo]) -> bool:
    instance, _, variable = target.partition(".")
    return instance in infos and variable in infos[instance].variables


def check_interface(scenario: Scenario, infos: dict[str, FMUInfo]) -> None:
    """Refuse (exit 2) a run whose connections or required roles name variables its FMUs lack,
    listing the FMUs' inputs and outputs and proposing the block that would fit."""
    roles = scenario.resolved_roles()
    lines = []
    for position, (source, target) in enumerate(scenario.connection_pairs()):
        for side, end in (("source", source), ("target", target)):
            if not _exists(end, infos):
                instance, _, variable = end.partition(".")
                lines.append(
                    f"connections[{position}] {side} {end!r}: {infos[instance].path.name} (instance {instance!r})"
                    f" has no variable {variable!r}"
                )
    for role in REQUIRED_ROLES:
        named = roles.get(role)
        if named is None:
            lines.append(f"roles.{role} is null, but the drive needs it")
        elif not _exists(named, infos):
            instance = named.partition(".")[0]
            kind = _ROLE_CAUSALITY[role]
            lines.append(
                f"roles.{role}: the default {named!r} names no variable of {infos[instance].path.name}"
                f" (instance {instance!r}); its {kind}s: {', '.join(infos[instance].names(kind)) or 'none'}"
            )
    if not lines:
        return
    listing = "\n".join(_listing(name, info) for name, info in infos.items())
    raise InputError(
        f"{scenario.source}: the FMUs' variables do not match the connections and roles: " + "; ".join(lines) + ".\n"
        f"The FMUs have:\n{listing}\n"
        "A connections and roles block that would fit (matched by causality, unit and name; check it,"
        " then put it into the scenario; docs/running.md, roles):\n" + propose_interface(scenario, infos)
    )


def _listing(name: str, info: FMUInfo) -> str:
    """One instance's inputs and outputs with their units."""

    def described(kind: str) -> str:
        items = [f"{v} [{info.variables[v].unit or '-'}]" for v in info.names(kind)]
        return ", ".join(items) or "none"

    return f"  {name} ({info.path.name}): inputs {described('input')}; outputs {described('output')}"


def propose_interface(scenario: Scenario, infos: dict[str, FMUInfo]) -> str:
    """The ``connections`` and ``roles`` YAML block for these FMUs: every connection end and role kept
    where its variable exists, else the FMU's variable of the same instance, causality and unit whose
    name is nearest (each variable used once; none: the connection left out, the role null)."""
    wanted: dict[str, str] = {}  # name that is missing -> its causality
    roles = {role: target for role, target in scenario.resolved_roles().items() if target is not None}
    pairs = scenario.connection_pairs()
    for source, target in pairs:
        wanted.update({end: kind for end, kind in ((source, "output"), (target, "input")) if not _exists(end, infos)})
    for role, target in roles.items():
        if not _exists(target, infos) and target.partition(".")[0] in infos:
            wanted[target] = _ROLE_CAUSALITY[role]
    used = {end for pair in pairs for end in pair if _exists(end, infos)}
    found = _match(wanted, infos, used | {target for target in roles.values() if _exists(target, infos)})
    lines = ["connections:"]
    for source, target in pairs:
        ends = [end if _exists(end, infos) else found.get(end) for end in (source, target)]
        if None in ends:
            lines.append(f"  # [{source}, {target}] left out: no variable of that causality and unit to take it")
        else:
            lines.append(f"  - [{ends[0]}, {ends[1]}]")
    lines.append("roles:")
    for role in scenario.roles.model_dump():  # every role, so the block pasted leaves none to its default
        given = roles.get(role)
        fitting = None if given is None else given if _exists(given, infos) else found.get(given)
        lines.append(f"  {role}: {fitting or 'null'}")
    return "\n".join(lines)


def _match(wanted: dict[str, str], infos: dict[str, FMUInfo], used: set[str]) -> dict[str, str]:
    """Each wanted ``instance.variable`` -> an existing one of the same instance and causality, the unit
    the shipped interface gives it where both say one, nearest in name, not ``used`` already; greedy,
    best score first."""
    taken = set(used)
    scored = []
    for end, kind in wanted.items():
        instance, _, variable = end.partition(".")
        if instance not in infos:
            continue
        unit = SHIPPED_UNITS.get(variable, "")
        for candidate in infos[instance].variables.values():
            if candidate.causality != kind or candidate.type != "Real":
                continue
            if unit and candidate.unit and candidate.unit != unit:
                continue
            score = _name_score(variable, candidate.name) - (0.5 if unit and not candidate.unit else 0.0)
            scored.append((score, end, f"{instance}.{candidate.name}"))
    found: dict[str, str] = {}
    for _score, end, name in sorted(scored, key=lambda item: -item[0]):
        if end not in found and name not in taken:
            found[end] = name
            taken.add(name)
    return found


def _name_score(expected: str, name: str) -> float:
    """How near ``name`` is to ``expected``: 3 equal but for case and underscores, 2 one contains the other,
    else the similarity ratio in [0, 1] (difflib)."""
    a, b = _plain(expected), _plain(name)
    if a == b:
        return 3.0
    if a in b or b in a:
        return 2.0
    return difflib.SequenceMatcher(None, a, b).ratio()


def _plain(name: str) -> str:
    return re.sub(r"[^0-9a-z]", "", name.lower())
