"""Which FMU output feeds which input, checked, and the order connections are copied in.

:class:`ConnectionGraph` checks every connection and master input against the FMUs'
model descriptions (an output to an input, compatible types and units, no input driven twice),
sorts the connections so that an output is read only after the inputs it depends on directly
(the FMUs' ``ModelStructure``) have been set, and tears algebraic loops: in each cycle of direct
feedthrough the connection given first is torn, its input becoming an iteration variable of
:class:`~heliostep.cosim.loops.LoopSolver`. :class:`~heliostep.cosim.master.CoSimulation` is
such a graph that can also be simulated.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

from heliostep.cosim.fmi import FMUInfo
from heliostep.cosim.fmi3_types import integer_range, type_label
from heliostep.cosim.signals import Connection, PiecewiseConstant
from heliostep.errors import InputError

#: Connectable types (FMI 2.0's names, FMI 3.0's Float64/Int32 as "Real"/"Integer"): a connection's two
#: ends must fall in the same class; an integer target must hold every value of its source's type
#: (:func:`_compatible`). Master inputs (numbers) drive every class but String and Binary.
_TYPE_CLASS = {
    **{name: "Real" for name in ("Real", "Float32")},
    **{
        name: "Integer"
        for name in ("Integer", "Enumeration", "Int8", "UInt8", "Int16", "UInt16", "UInt32", "Int64", "UInt64")
    },
    "Boolean": "Boolean",
    "String": "String",
    "Binary": "Binary",
}


def _compatible(source, target) -> str:
    """Why ``source`` cannot feed ``target`` (VariableInfo), or "" when it can."""
    if _TYPE_CLASS[source.type] != _TYPE_CLASS[target.type]:
        return "types are incompatible"
    source_range, target_range = integer_range(source), integer_range(target)
    if source_range is None or target_range is None or source.type == target.type == "Enumeration":
        return ""
    (low, high), (target_low, target_high) = source_range, target_range
    if low < target_low or high > target_high:
        return f"types are incompatible: {target.name} cannot hold every value of {source.name} [{low}, {high}]"
    return ""


def split_name(qualified: str, what: str) -> tuple[str, str]:
    instance, dot, variable = qualified.partition(".")
    if not dot or not instance or not variable:
        raise InputError(f"{what} {qualified!r}: expected 'instance.variable'")
    return instance, variable


class ConnectionGraph:
    """FMU instances, the connections between them and the master inputs that drive them, checked.

    ``order`` lists the continuous and discrete connections in propagation order (torn ones
    left out), ``torn`` the connections torn to break algebraic loops and ``loops`` a
    description of each loop.
    """

    def __init__(
        self,
        fmus: Mapping[str, FMUInfo],
        connections: Sequence[Connection] = (),
        inputs: Sequence[PiecewiseConstant] = (),
    ):
        self.fmus = dict(fmus)
        self.inputs = list(inputs)
        self.connections = self._check_connections(connections)
        self.order = self._propagation_order()
        self._check_units()

    def _variable(self, qualified: str, what: str, causality: str):
        instance, variable = split_name(qualified, what)
        if instance not in self.fmus:
            raise InputError(f"{what} {qualified!r}: no FMU instance {instance!r}; instances: {', '.join(self.fmus)}")
        info = self.fmus[instance]
        if variable not in info.variables:
            names = info.outputs if causality == "output" else info.inputs
            raise InputError(
                f"{what} {qualified!r}: {info.path.name} has no variable {variable!r}; "
                f"its {causality}s: {', '.join(names)}"
            )
        var = info.variables[variable]
        if var.causality != causality:
            raise InputError(f"{what} {qualified!r}: expected an {causality}, it is a {var.type} {var.causality}")
        if var.type not in _TYPE_CLASS or (what.startswith("input ") and var.type in ("String", "Binary")):
            raise InputError(f"{what} {qualified!r}: {type_label(var)} variables cannot be connected or driven")
        return instance, var

    def _check_connections(self, connections: Sequence[Connection]) -> list[Connection]:
        driven: dict[str, str] = {}
        for item in self.inputs:
            if not item.target:  # a traced value that drives nothing (a sampled component's output)
                continue
            self._variable(item.target, f"input {item.name} target", "input")
            driven[item.target] = f"master input {item.name}"
        for c in connections:
            self._variable(c.source, "connection source", "output")
            self._variable(c.target, "connection target", "input")
            if c.target in driven:
                raise InputError(f"{c.target} is driven twice: by {driven[c.target]} and by {c.source}")
            driven[c.target] = c.source
        return list(connections)

    def _check_units(self) -> None:
        for c in self.connections:
            _, source = self._variable(c.source, "connection source", "output")
            _, target = self._variable(c.target, "connection target", "input")
            problem = _compatible(source, target)
            if problem:
                raise InputError(
                    f"connection {c.source} -> {c.target}: {problem} "
                    f"({c.source} is {type_label(source)}, {c.target} is {type_label(target)})"
                )
            if c.transform is not None:
                if source.type != "Real" or target.type != "Real":
                    raise InputError(
                        f"connection {c.source} -> {c.target}: a linear transformation needs Real ends "
                        f"({c.source} is {type_label(source)}, {c.target} is {type_label(target)})"
                    )
                continue  # the transformation converts between the ends' units
            if source.unit and target.unit and source.unit != target.unit:
                raise InputError(
                    f"connection {c.source} -> {c.target}: units differ ({source.unit!r} vs {target.unit!r})"
                )

    def _prerequisites(self, c: Connection) -> list[Connection]:
        """Connections that set an input which ``c``'s source output depends on directly."""
        feeds = {x.target: x for x in self.connections}  # input -> connection driving it
        instance, output = split_name(c.source, "connection source")
        depends = self.fmus[instance].output_feedthrough.get(output, [])
        return [feeds[f"{instance}.{name}"] for name in depends if f"{instance}.{name}" in feeds]

    def is_discrete(self, c: Connection) -> bool:
        """Exchanged only at events: either end is a discrete-time variable."""
        _, source = self._variable(c.source, "connection source", "output")
        _, target = self._variable(c.target, "connection target", "input")
        return source.discrete or target.discrete

    def propagation_groups(self) -> list[tuple[str, str, list[Connection]]]:
        """Connections batched as (source instance, target instance, connections), in an order
        where each batch's outputs depend only on inputs set by earlier batches."""
        level: dict[Connection, int] = {}
        for c in self.order:  # prerequisites come earlier in self.order
            level[c] = 1 + max((level[p] for p in self._prerequisites(c) if p not in self.torn), default=0)
        groups: dict[tuple[int, str, str], list[Connection]] = {}
        for c in self.order:
            key = (level[c], split_name(c.source, "source")[0], split_name(c.target, "target")[0])
            groups.setdefault(key, []).append(c)
        return [(src, dst, members) for (_, src, dst), members in sorted(groups.items(), key=lambda kv: kv[0][0])]

    def _propagation_order(self) -> list[Connection]:
        """Connections sorted so that an output is read only after the inputs it depends on are set.

        Algebraic loops (cycles of direct feedthrough) are torn: in each cycle found, the
        connection that comes first in the order the connections were given is torn (its
        input becomes an iteration variable of :class:`~heliostep.cosim.loops.LoopSolver`),
        until no cycle is left. ``self.torn`` lists the torn connections and ``self.loops``
        describes each loop. Loops through discrete-time connections are refused.
        """
        self.torn: list[Connection] = []
        self.loops: list[str] = []
        index = {c: k for k, c in enumerate(self.connections)}
        while True:
            order: list[Connection] = []
            state: dict[Connection, int] = {}  # 1 visiting, 2 done
            cycle_found: list[Connection] = []

            def visit(  # this iteration's search state bound as defaults: each round searches afresh
                c: Connection,
                path: list[Connection],
                state: dict[Connection, int] = state,
                order: list[Connection] = order,
                cycle_found: list[Connection] = cycle_found,
            ) -> bool:
                if state.get(c) == 2:
                    return False
                if state.get(c) == 1:
                    cycle_found.extend(path[path.index(c) :])
                    return True
                state[c] = 1
                for before in self._prerequisites(c):
                    if before not in self.torn and visit(before, path + [c]):
                        return True
                state[c] = 2
                order.append(c)
                return False

            if not any(visit(c, []) for c in self.connections if c not in self.torn):
                return [c for c in order if c not in self.torn]
            cycle = cycle_found[::-1]  # in the direction values flow
            tear = min(cycle, key=index.__getitem__)
            k = cycle.index(tear)
            cycle = cycle[k:] + cycle[:k]  # described from the torn connection on
            description = " -> ".join(f"{x.source} -> {x.target}" for x in cycle)
            discrete = [x for x in cycle if self.is_discrete(x)]
            if discrete:
                raise InputError(
                    f"algebraic loop of direct feedthrough between FMUs: {description}; "
                    f"it runs through the discrete-time connection {discrete[0].source} -> "
                    f"{discrete[0].target} and cannot be solved: break it with a state "
                    "or remove a connection"
                )
            self.torn.append(tear)
            self.loops.append(f"{description} (torn at {tear.target})")
