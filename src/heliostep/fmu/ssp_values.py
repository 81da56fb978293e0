"""Parameter bindings of an SSP 1.0 system: ``.ssv`` parameter sets and ``.ssm`` parameter mappings (in files
of the archive or inline) onto the flattened FMU instances' variables.

SSP 1.0's rules (the SSD schema's ParameterBinding): a binding's ``prefix`` is put before every name of its
parameter set; a mapping entry renames a (prefixed) name to its ``target`` and may transform the value
(``ssc:LinearTransformation`` for Real values, the Integer, Boolean and Enumeration mapping tables for
those); names the mapping does not list keep their own; a name is resolved in the bound element (a
component: its FMU variable; a system: ``element.name`` down its hierarchy, or one of its connectors,
whose value goes on through the connections to the FMU variables they reach); a name that matches
nothing is ignored. Bindings at a higher level of the hierarchy win over lower ones, and among one
element's bindings a later one wins. A Real value whose unit is not its variable's is converted
(unless the mapping entry suppresses unit conversion).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from heliostep.errors import InputError
from heliostep.fmu.ssp_read import NS, Flattener, child
from heliostep.fmu.ssp_units import IDENTITY, applied, conversion, then, unit_definitions

_SET_TYPE = "application/x-ssp-parameter-set"
_MAPPING_TYPE = "application/x-ssp-parameter-mapping"
_TABLES: dict[str, Callable[[str], Any]] = {
    "IntegerMappingTransformation": int,
    "BooleanMappingTransformation": lambda text: text.strip().lower() in ("true", "1"),
    "EnumerationMappingTransformation": str,
}


class Binder:
    """The parameters of ``flat``'s system: ``read_xml(member, schema)`` reads (and validates against that
    SSP schema) an archive member's XML; ``validate(element, schema)`` an inline one."""

    def __init__(self, flat: Flattener, read_xml: Callable[[str, str], Any], validate: Callable[[Any, str], None]):
        self.flat, self.read_xml, self.validate = flat, read_xml, validate
        self.values: dict[tuple[str, ...], dict[str, object]] = {}  # component path -> variable -> value
        system, xml = flat.systems[()]
        self._bind_system((), system, xml)

    def parameters(self) -> dict[str, dict[str, object]]:
        return {self.flat.instances[path]: values for path, values in self.values.items() if values}

    def _bind_system(self, path: tuple[str, ...], system, xml) -> None:
        """Post-order: the elements' bindings first, then the system's own (a higher level wins)."""
        for element in system.elements:
            if type(element).__name__ == "System":
                self._bind_system((*path, element.name), *self.flat.systems[(*path, element.name)])
            else:
                self._bind(element, child(xml, "Component", element.name), (*path, element.name), True)
        self._bind(system, xml, path, False)

    def _bind(self, element, xml, path: tuple[str, ...], component: bool) -> None:
        what = f"ssd:{'Component' if component else 'System'} {element.name!r}"
        raws = xml.findall("ssd:ParameterBindings/ssd:ParameterBinding", NS)
        for binding, raw in zip(element.parameterBindings, raws):
            where = f"{self.flat.path}: ssd:ParameterBinding of {what}"
            if (raw.get("type") or _SET_TYPE) != _SET_TYPE:
                raise InputError(f"{where}: parameter source type {raw.get('type')!r} is not supported ({_SET_TYPE})")
            sets = [self.read_xml(raw.get("source"), "SystemStructureParameterValues.xsd")] if raw.get("source") else []
            for inline in raw.findall("ssd:ParameterValues/ssv:ParameterSet", NS):
                self.validate(inline, "SystemStructureParameterValues.xsd")
                sets.append(inline)
            mapping = self._mapping(raw, where)
            prefix = binding.prefix or ""
            for values, set_xml in zip(binding.parameterValues, sets):
                units = {**self.flat.units, **unit_definitions(_units(set_xml))}  # the set's own first
                for parameter in values.parameters:
                    name = prefix + parameter.name
                    said = f"{where}: ssv:Parameter {name!r}"
                    for target, entry in mapping.get(name, [(name, None)]):
                        self._apply(path, component, target, parameter, entry, units, said)

    def _mapping(self, raw, where: str) -> dict[str, list[tuple[str, Any]]]:
        """Source name -> [(target name, its mapping entry)] of the binding's ``ssd:ParameterMapping``."""
        element = raw.find("ssd:ParameterMapping", NS)
        if element is None:
            return {}
        if (element.get("type") or _MAPPING_TYPE) != _MAPPING_TYPE:
            raise InputError(f"{where}: parameter mapping type {element.get('type')!r} is not supported")
        if element.get("source"):
            root = self.read_xml(element.get("source"), "SystemStructureParameterMapping.xsd")
        else:
            root = element.find("ssm:ParameterMapping", NS)
            if root is None:
                return {}
            self.validate(root, "SystemStructureParameterMapping.xsd")
        mapping: dict[str, list[tuple[str, Any]]] = {}
        for entry in root.findall("ssm:MappingEntry", NS):
            mapping.setdefault(entry.get("source"), []).append((entry.get("target"), entry))
        return mapping

    # ------------------------------------------------------------------ one value onto its variables
    def _apply(self, path, component: bool, name: str, parameter, entry, units, where: str) -> None:
        """``parameter`` (its name mapped to ``name``) onto the variables ``name`` resolves to: a Real value
        converted to the unit where it is bound, then the mapping's transformation, then the connections'
        (a system connector's value going on to the FMU variables)."""
        suppress = entry is not None and entry.get("suppressUnitConversion", "false") in ("true", "1")
        if component:
            variables = self.flat.ports[path]
            targets = [(path, name, IDENTITY, _unit(variables[name]))] if name in variables else []
        else:
            targets = self._resolve(path, name)
        for component_path, variable_name, onward, bound_unit in targets:
            variable = self.flat.ports[component_path][variable_name]
            value = _typed(parameter, variable, entry, where)
            if parameter.type == "Real":
                convert = IDENTITY
                if parameter.unit and bound_unit and parameter.unit != bound_unit and not suppress:
                    convert = conversion(parameter.unit, bound_unit, units, where)
                value = applied(then(then(convert, _linear(entry)), onward), float(value))  # type: ignore[arg-type]
            elif onward != IDENTITY:
                raise InputError(f"{where}: a {parameter.type} value through a transforming connection")
            self.values.setdefault(component_path, {})[variable_name] = value

    def _resolve(self, system: tuple[str, ...], name: str) -> list:
        """(component path, variable, the map from where the value is bound on, the unit there) for ``name``
        in the system at ``system``: a component's variable, or the FMU variables a system connector's
        connections reach; [] when it matches nothing."""
        head, dot, rest = name.partition(".")
        if dot and (*system, head) in self.flat.ports:
            variables = self.flat.ports[(*system, head)]
            return [((*system, head), rest, IDENTITY, _unit(variables[rest]))] if rest in variables else []
        if dot and (*system, head) in self.flat.systems:
            return self._resolve((*system, head), rest)
        if name not in {c.name for c in self.flat.systems[system][0].connectors}:
            return []
        start = ("sys", system, name)
        at = self.flat.unit(start)
        return [
            (node[1], node[2], transform, at)
            for node, transform, _, _, _ in self.flat.reach(start, at)
            if self.flat.causality(node) in ("parameter", "input")
        ]


def _units(xml) -> list:
    """The ``ssc:Unit`` definitions a parameter set carries, as objects like fmpy's."""
    from fmpy.ssp.ssd import Unit

    units = []
    for unit in xml.findall("ssv:Units/ssc:Unit", NS):
        base = unit.find("ssc:BaseUnit", NS)
        units.append(Unit(name=unit.get("name"), **(dict(base.attrib) if base is not None else {})))
    return units


def _unit(variable) -> str | None:
    return getattr(variable, "unit", None) or getattr(getattr(variable, "declaredType", None), "unit", None)


def _linear(entry) -> tuple[float, float]:
    linear = entry.find("ssc:LinearTransformation", NS) if entry is not None else None
    return IDENTITY if linear is None else (float(linear.get("factor", "1")), float(linear.get("offset", "0")))


def _table(entry) -> tuple[str, dict] | None:
    """The mapping entry's table transformation: (Integer, Boolean or Enumeration, source -> target)."""
    for tag, convert in _TABLES.items():
        element = entry.find(f"ssc:{tag}", NS) if entry is not None else None
        if element is not None:
            table = {convert(e.get("source")): convert(e.get("target")) for e in element.findall("ssc:MapEntry", NS)}
            return tag.removesuffix("MappingTransformation"), table
    return None


def _typed(parameter, variable, entry, where: str) -> object:
    """The parameter's value as the scenario holds it, after its mapping entry's table (if any)."""
    kind, text = parameter.type, parameter.value
    if kind not in ("Real", "Integer", "Boolean", "Enumeration", "String"):
        raise InputError(f"{where}: {kind or 'untyped'} parameter values are not supported")
    if _linear(entry) != IDENTITY and kind != "Real":
        raise InputError(f"{where}: ssc:LinearTransformation on a {kind} value (it is for Real values)")
    table = _table(entry)
    if table is not None and (table[0], kind) not in (
        ("Integer", "Integer"),
        ("Integer", "Enumeration"),
        ("Boolean", "Boolean"),
        ("Enumeration", "Enumeration"),
    ):
        raise InputError(f"{where}: ssc:{table[0]}MappingTransformation on a {kind} value")
    if kind == "Real":
        return float(text)
    if kind == "String":
        return str(text)
    if kind == "Boolean":
        value: Any = str(text).strip().lower() in ("true", "1")
    elif kind == "Integer":
        value = int(text)
    else:  # an enumeration item: mapped by name, then its value in the variable's type
        value = str(text)
        if table is not None and table[0] == "Enumeration":
            value, table = table[1].get(value, value), None
        value = _enumeration_value(value, variable, where)
    return value if table is None else table[1].get(value, value)


def _enumeration_value(item: str, variable, where: str) -> int:
    """An enumeration item's value by its name in the variable's type (a number as it is)."""
    if item.lstrip("+-").isdigit():
        return int(item)
    items = getattr(getattr(variable, "declaredType", None), "items", None) or []
    for candidate in items:
        if candidate.name == item:
            return int(candidate.value)
    names = ", ".join(str(c.name) for c in items) or "none"
    raise InputError(f"{where}: {item!r} is not an item of {variable.name}'s enumeration (items: {names})")
