"""An SSP 1.0 system as other tools write it, flattened into FMU instances, connections and parameters.

fmpy's SSD reader validates the file against the SSP 1.0 schemas it ships and gives the systems, their
elements, connectors, connections and parameter bindings (its ``.ssv`` and ``.ssm`` files validated too);
what it leaves out is read from the same XML here: connectors' units, connections' transformations and
``suppressUnitConversion``, inline parameter mappings and mapping transformations. Nested systems are
flattened: a component's instance is its path of element names below the top system joined by ``_``,
and a connection through a system's connectors becomes one connection from the FMU output to each FMU
input it reaches, its transformations and unit conversions composed (:mod:`heliostep.fmu.ssp_units`).
Parameters: :mod:`heliostep.fmu.ssp_values`. What is not taken is an InputError naming the element,
its name and the file.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from heliostep.errors import InputError
from heliostep.fmu.ssp_units import IDENTITY, conversion, then, unit_definitions

#: The SSP 1.0 namespaces.
NS = {
    "ssc": "http://ssp-standard.org/SSP1/SystemStructureCommon",
    "ssd": "http://ssp-standard.org/SSP1/SystemStructureDescription",
    "ssv": "http://ssp-standard.org/SSP1/SystemStructureParameterValues",
    "ssm": "http://ssp-standard.org/SSP1/SystemStructureParameterMapping",
}
#: The MIME type of an FMU component in SSP 1.0.
FMU_TYPE = "application/x-fmu-sharedlibrary"
_MAPPINGS = ("BooleanMappingTransformation", "IntegerMappingTransformation", "EnumerationMappingTransformation")
_NOT_IDENTIFIER = re.compile(r"[^A-Za-z0-9_]")


@dataclass
class FlatSystem:
    """The flattened system: instance -> (component path, archive member), connections as (source,
    target), target -> (factor, offset) where a connection transforms its value, parameters per instance."""

    components: dict[str, tuple[tuple[str, ...], str]] = field(default_factory=dict)
    connections: list[tuple[str, str]] = field(default_factory=list)
    transformations: dict[str, tuple[float, float]] = field(default_factory=dict)
    parameters: dict[str, dict[str, object]] = field(default_factory=dict)


def instance_name(path: tuple[str, ...]) -> str:
    """A component's instance name: its element names below the top system joined by ``_`` (characters
    other than letters, digits and ``_`` as ``_``; a leading digit after a ``_``)."""
    name = _NOT_IDENTIFIER.sub("_", "_".join(path))
    return f"_{name}" if name[:1].isdigit() else name


def child(element, tag: str, name: str):
    """The ``ssd:Elements`` child of ``element`` with that tag and name (the raw XML)."""
    for item in element.findall(f"ssd:Elements/ssd:{tag}", NS):
        if item.get("name") == name:
            return item
    return None


def transformation(element, where: str) -> tuple[float, float] | None:
    """The ``ssc:LinearTransformation`` under ``element`` as (factor, offset), None without; a mapping
    transformation is refused naming ``where`` (only parameter mappings take those)."""
    linear = element.find("ssc:LinearTransformation", NS)
    if linear is not None:
        return float(linear.get("factor", "1")), float(linear.get("offset", "0"))
    for kind in _MAPPINGS:
        if element.find(f"ssc:{kind}", NS) is not None:
            raise InputError(
                f"{where} has an ssc:{kind}, which heliostep takes in parameter mappings only, not on connections"
            )
    return None


class Flattener:
    """The walk over an SSD's systems: ``ssd`` is fmpy's tree, ``root`` the SSD's XML root, ``ports`` the
    FMU variables of each component path (name -> fmpy variable), ``units`` the unit definitions."""

    def __init__(self, path: Path, ssd, root, describe):
        self.path, self.ssd, self.root = path, ssd, root
        self.describe = describe  # (component path, archive member) -> (variables by name, unit definitions)
        self.result = FlatSystem()
        self.systems: dict[tuple[str, ...], tuple[Any, Any]] = {}  # path -> (fmpy System, XML element)
        self.ports: dict[tuple[str, ...], dict[str, Any]] = {}
        self.instances: dict[tuple[str, ...], str] = {}
        self.connector_units: dict[tuple[str, tuple[str, ...], str], str] = {}
        #: node -> (the node at the connection's other end, its transformation, suppressUnitConversion,
        #: the connection as named in messages, its place in the file's order)
        self.edges: dict[tuple, list[tuple[tuple, tuple[float, float] | None, bool, str, int]]] = {}
        self._fmu_units: list = []
        self._collect(ssd.system, root.find("ssd:System", NS), ())
        self.units = unit_definitions(getattr(ssd, "units", []), [u for units in self._fmu_units for u in units])
        for system_path in self.systems:
            self._connect(system_path)
        self._flatten_connections()

    # ------------------------------------------------------------------ the elements
    def _collect(self, system, xml, path: tuple[str, ...]) -> None:
        self.systems[path] = (system, xml)
        self._note_units("sys", path, xml)
        for element in system.elements:
            kind = type(element).__name__
            where = f"{self.path}: {'ssd:System' if kind == 'System' else 'ssd:' + kind} {element.name!r}"
            if kind == "System":
                self._collect(element, child(xml, "System", element.name), (*path, element.name))
                continue
            if kind != "Component":
                raise InputError(f"{where} is not supported (components and systems only)")
            if element.type not in (None, FMU_TYPE):
                raise InputError(f"{where} is of type {element.type!r}, not an FMU ({FMU_TYPE}): not supported")
            component = (*path, element.name)
            name = instance_name(component)
            for other, taken in self.instances.items():
                if taken == name:
                    raise InputError(
                        f"{where}: its instance name {name!r} is also that of {'.'.join(other)!r}; rename one"
                    )
            self.instances[component] = name
            member = _member(element.source, where, self.path)
            self.result.components[name] = (component, member)
            variables, units = self.describe(component, member)
            self.ports[component] = variables
            self._fmu_units.append(units)
            raw = child(xml, "Component", element.name)
            self._note_units("comp", component, raw)
            for connector in raw.findall("ssd:Connectors/ssd:Connector", NS):
                self._check_connector(component, connector, where)

    def _note_units(self, kind: str, path: tuple[str, ...], xml) -> None:
        for connector in xml.findall("ssd:Connectors/ssd:Connector", NS):
            real = connector.find("ssc:Real", NS)
            if real is not None and real.get("unit"):
                self.connector_units[(kind, path, connector.get("name"))] = real.get("unit")

    def _check_connector(self, component: tuple[str, ...], connector, where: str) -> None:
        """A component's connector names a variable of its FMU, with the FMU's unit where both say one."""
        name = connector.get("name")
        variable = self.ports[component].get(name)
        if variable is None:
            raise InputError(f"{where}: ssd:Connector {name!r} is not a variable of its FMU")
        declared = self.connector_units.get(("comp", component, name))
        unit = _unit(variable)
        if declared and unit and declared != unit:
            raise InputError(
                f"{where}: ssd:Connector {name!r} has unit {declared!r}, its FMU's variable {unit!r}:"
                " a connector's unit must be its variable's"
            )

    # ------------------------------------------------------------------ the connections
    def node(self, system_path: tuple[str, ...], element: str | None, connector: str, where: str) -> tuple:
        """("comp" or "sys", path, connector) of a connection's end in the system at ``system_path``."""
        if element is None:
            return ("sys", system_path, connector)
        path = (*system_path, element)
        if path in self.ports:
            if connector not in self.ports[path]:
                raise InputError(f"{where}: {element}.{connector} is not a variable of that component's FMU")
            return ("comp", path, connector)
        if path in self.systems:
            return ("sys", path, connector)
        raise InputError(f"{where}: no element {element!r} in system {'.'.join(system_path) or '(top)'}")

    def _connect(self, system_path: tuple[str, ...]) -> None:
        system, xml = self.systems[system_path]
        for c, raw in zip(system.connections, xml.findall("ssd:Connections/ssd:Connection", NS)):
            start = f"{c.startElement}.{c.startConnector}" if c.startElement else c.startConnector
            end = f"{c.endElement}.{c.endConnector}" if c.endElement else c.endConnector
            inside = f" in system {'.'.join(system_path)!r}" if system_path else ""
            where = f"{self.path}: ssd:Connection {start} -> {end}{inside}"
            a = self.node(system_path, c.startElement, c.startConnector, where)
            b = self.node(system_path, c.endElement, c.endConnector, where)
            for end_node in (a, b):
                if end_node[0] == "comp" and self.causality(end_node) == "calculatedParameter":
                    raise InputError(f"{where}: connections of calculated parameters are not supported")
            linear = transformation(raw, where)
            suppress = raw.get("suppressUnitConversion", "false") in ("true", "1")
            order = sum(map(len, self.edges.values())) // 2
            self.edges.setdefault(a, []).append((b, linear, suppress, where, order))
            self.edges.setdefault(b, []).append((a, linear, suppress, where, order))

    def causality(self, node: tuple) -> str:
        return self.ports[node[1]][node[2]].causality

    def unit(self, node: tuple) -> str | None:
        """The unit of a connection end: its connector's, else (a component's) its FMU variable's."""
        declared = self.connector_units.get(node)
        if declared or node[0] == "sys":
            return declared
        return _unit(self.ports[node[1]][node[2]])

    def reach(self, start: tuple, unit: str | None):
        """Every component connector reached from ``start`` through connections and systems' connectors:
        (node, the map from the value at ``start`` to the value there, whether any transformation or unit
        conversion was met, the connection reaching it and its place in the file)."""
        found, seen = [], {start}
        stack = [(start, IDENTITY, unit, False)]
        while stack:
            node, transform, current, explicit = stack.pop()
            for other, linear, suppress, where, order in self.edges.get(node, []):
                if other in seen:
                    continue
                seen.add(other)
                unit_there = self.unit(other) or current
                step, converted = IDENTITY, False
                if current and unit_there and current != unit_there:
                    converted = True
                    if not suppress:
                        step = conversion(current, unit_there, self.units, where)
                step = then(step, linear or IDENTITY)
                reached = (other, then(transform, step), unit_there, explicit or converted or linear is not None)
                if other[0] == "comp":
                    found.append((other, reached[1], reached[3], where, order))
                else:
                    stack.append(reached)
        return found

    def _flatten_connections(self) -> None:
        """One connection from each FMU output to each FMU input it reaches, in the order of the file's
        connections that reach the inputs (a flat system's connections in their own order)."""
        flat = []
        for node in (n for n in self.edges if n[0] == "comp" and self.causality(n) == "output"):
            source = f"{self.instances[node[1]]}.{node[2]}"
            for other, transform, explicit, where, order in self.reach(node, self.unit(node)):
                causality = self.causality(other)
                if causality == "output":
                    raise InputError(f"{where}: it connects two outputs ({source} and {'.'.join(other[1])}.{other[2]})")
                if causality != "input":
                    raise InputError(f"{where}: an output connected to the {causality} {other[2]!r}: not supported")
                flat.append((order, source, f"{self.instances[other[1]]}.{other[2]}", transform if explicit else None))
        for _, source, target, transform in sorted(flat, key=lambda item: item[0]):
            self.result.connections.append((source, target))
            if transform is not None:
                self.result.transformations[target] = transform


def _unit(variable) -> str | None:
    return getattr(variable, "unit", None) or getattr(getattr(variable, "declaredType", None), "unit", None)


def _member(source: str | None, where: str, path: Path) -> str:
    """The archive member a relative ``source`` URI names (``./`` and percent-escapes resolved)."""
    from urllib.parse import unquote, urlsplit

    parts = urlsplit(source or "")
    if parts.scheme or parts.netloc:
        raise InputError(f"{where}: its source {source!r} is not in the file {path} (only relative sources are)")
    return unquote(parts.path).removeprefix("./")
