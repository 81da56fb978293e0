"""SSP 1.0 systems: a scenario's FMUs, connections and parameters read from and written to an ``.ssp``.

Details: docs/fmus.md, ``heliostep.fmu.ssp``.
"""

from __future__ import annotations

import hashlib
import os
import tempfile
import zipfile
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from xml.sax.saxutils import quoteattr

from heliostep.errors import InputError
from heliostep.file_modes import publish
from heliostep.input_files import MAX_ARCHIVE_BYTES, read_input_bytes

__all__ = ["FMU_TYPE", "SSPSystem", "read_ssp", "write_ssp"]

#: The MIME type of an FMU component in SSP 1.0.
FMU_TYPE = "application/x-fmu-sharedlibrary"
_FIXED_TIME = (1980, 1, 1, 0, 0, 0)
#: FMI type -> SSP 1.0 connector type (FMI 3.0's types onto SSP's Real and Integer; an Enumeration,
#: which in SSP needs its type's name, as Integer); Real, Integer, Boolean, String and Binary as they are
_SSP_TYPES = {"Enumeration": "Integer", "Float64": "Real", "Float32": "Real"}
_SSP_TYPES.update({f"{sign}Int{bits}": "Integer" for sign in ("", "U") for bits in (8, 16, 32, 64)})


@dataclass
class SSPSystem:
    """What a scenario takes from an SSP: instance -> FMU file, connections, instance -> parameters."""

    fmus: dict[str, Path] = field(default_factory=dict)
    connections: list[tuple[str, str]] = field(default_factory=list)
    parameters: dict[str, dict[str, object]] = field(default_factory=dict)


def _value(parameter) -> object:
    """An SSV parameter's value as the scenario holds it."""
    text = parameter.value
    if parameter.type == "Real":
        return float(text)
    if parameter.type in ("Integer", "Enumeration"):
        return int(text)
    if parameter.type == "Boolean":
        return str(text).strip().lower() in ("true", "1")
    return str(text)


def read_ssp(path: str | Path, cache: Path) -> SSPSystem:
    """The system of an SSP 1.0 file (see the module docstring); InputError naming the file otherwise."""
    from fmpy.ssp.ssd import Component, read_ssd

    path = Path(path)
    if not path.exists():
        raise InputError(f"SSP file not found: {path}")
    digest = hashlib.sha256(read_input_bytes(path, "SSP", MAX_ARCHIVE_BYTES)).hexdigest()
    try:
        ssd = read_ssd(str(path), validate=True)
    except Exception as exc:  # a damaged zip, no SystemStructure.ssd, or a schema violation
        first = str(exc).strip().splitlines()
        raise InputError(f"{path}: not a valid SSP 1.0 file ({' '.join(first[:2]) or type(exc).__name__})") from None
    system, result = ssd.system, SSPSystem()
    folder = Path(cache) / "ssp" / digest[:16]
    for element in system.elements:
        if not isinstance(element, Component):
            raise InputError(f"{path}: element {element.name!r} is not a component (nested systems are not supported)")
        if element.type not in (None, FMU_TYPE):
            raise InputError(f"{path}: component {element.name!r} is of type {element.type!r}, not an FMU ({FMU_TYPE})")
        try:
            result.fmus[element.name] = _extracted(path, element.name, element.source, folder)
        except OSError as exc:
            raise InputError(
                f"{path}: component {element.name!r}: cannot extract its FMU into the FMU cache {cache}"
                f" ($HELIOSTEP_FMUS): {exc.strerror or exc}; point HELIOSTEP_FMUS at a writable folder"
            ) from None
        _bind(result, element.parameterBindings, element.name, path)
    _bind(result, system.parameterBindings, None, path)
    for c in system.connections:
        if c.startElement is None or c.endElement is None:
            raise InputError(
                f"{path}: connection {c.startConnector} -> {c.endConnector} uses the system's own connectors,"
                " which heliostep does not take (connect components only)"
            )
        if getattr(c, "linearTransformation", None) is not None:
            raise InputError(f"{path}: connection {c.startElement}.{c.startConnector} has a transformation")
        result.connections.append((f"{c.startElement}.{c.startConnector}", f"{c.endElement}.{c.endConnector}"))
    return result


def _bind(result: SSPSystem, bindings, component: str | None, path: Path) -> None:
    """Parameter values of ``bindings`` into ``result.parameters`` (names ``component.parameter`` at system level)."""
    for binding in bindings:
        if binding.parameterMapping:
            raise InputError(f"{path}: a parameter binding with a ParameterMapping is not supported")
        for values in binding.parameterValues:
            for parameter in values.parameters:
                name = (binding.prefix or "") + parameter.name
                instance, variable = (
                    (component, name) if component else name.split(".", 1) if "." in name else ("", name)
                )
                if not instance:
                    raise InputError(f"{path}: system parameter {name!r} names no component ('component.parameter')")
                result.parameters.setdefault(instance, {})[variable] = _value(parameter)


def _extracted(path: Path, name: str, source: str | None, folder: Path) -> Path:
    """The component's FMU extracted from the SSP into ``folder`` (reused when already there, whole)."""
    member = (source or "").removeprefix("./")
    with zipfile.ZipFile(path) as archive:
        if member not in archive.namelist():
            raise InputError(f"{path}: component {name!r}: its source {source!r} is not in the file")
        if archive.getinfo(member).file_size > MAX_ARCHIVE_BYTES:
            raise InputError(f"{path}: component {name!r}: its source {source!r} unpacks to more than an FMU may be")
        data = archive.read(member)
    target = folder / Path(member).name
    if target.is_file() and target.read_bytes() == data:
        return target
    folder.mkdir(parents=True, exist_ok=True)
    handle, partial = tempfile.mkstemp(dir=folder, prefix=".extract-")
    try:
        with os.fdopen(handle, "wb") as out:
            out.write(data)
        os.replace(partial, target)
    finally:
        if os.path.exists(partial):
            os.unlink(partial)
    return target


def _connectors(fmu: Path, units: dict[str, str]) -> list[str]:
    """The SSD connectors of an FMU's inputs, outputs and parameters (units collected into ``units``)."""
    from fmpy import read_model_description

    description = read_model_description(str(fmu), validate=False)
    for unit in description.unitDefinitions:
        base = unit.baseUnit
        exponents = {k: getattr(base, k, 0) for k in ("kg", "m", "s", "A", "K", "mol", "cd", "rad")} if base else {}
        attributes = " ".join(f'{k}="{v}"' for k, v in exponents.items() if v)
        if base is not None and getattr(base, "factor", 1.0) != 1.0:
            attributes += f' factor="{base.factor!r}"'
        if base is not None and getattr(base, "offset", 0.0) != 0.0:
            attributes += f' offset="{base.offset!r}"'
        units.setdefault(unit.name, f"<ssc:Unit name={quoteattr(unit.name)}><ssc:BaseUnit {attributes}/></ssc:Unit>")
    lines = []
    for v in description.modelVariables:
        if v.causality not in ("input", "output", "parameter"):
            continue
        kind = _SSP_TYPES.get(v.type, v.type)
        unit = getattr(v, "unit", None) or getattr(getattr(v, "declaredType", None), "unit", None)
        unit_attribute = f" unit={quoteattr(unit)}" if kind == "Real" and unit in units else ""
        lines.append(
            f"<ssd:Connector name={quoteattr(v.name)} kind={quoteattr(v.causality)}><ssc:{kind}{unit_attribute}/>"
            "</ssd:Connector>"
        )
    return lines


def _parameter(name: str, value: object) -> str:
    if isinstance(value, bool):
        kind, text = "Boolean", "true" if value else "false"
    elif isinstance(value, int):
        kind, text = "Integer", str(value)
    elif isinstance(value, float):
        kind, text = "Real", repr(value)
    else:
        kind, text = "String", str(value)
    return f"<ssv:Parameter name={quoteattr(name)}><ssv:{kind} value={quoteattr(text)}/></ssv:Parameter>"


def _component(instance: str, fmu: Path, values: Mapping[str, object], units: dict[str, str]) -> str:
    """One FMU instance as an SSD ``Component``: connectors, parameter bindings (units into ``units``)."""
    lines = [
        f"<ssd:Component name={quoteattr(instance)} type={quoteattr(FMU_TYPE)} "
        f"source={quoteattr(f'resources/{instance}.fmu')}>",
        "<ssd:Connectors>",
        *_connectors(fmu, units),
        "</ssd:Connectors>",
    ]
    if values:
        lines += [
            "<ssd:ParameterBindings><ssd:ParameterBinding><ssd:ParameterValues>",
            f'<ssv:ParameterSet version="1.0" name={quoteattr(instance)}><ssv:Parameters>',
            *(_parameter(k, v) for k, v in values.items()),
            "</ssv:Parameters></ssv:ParameterSet>",
            "</ssd:ParameterValues></ssd:ParameterBinding></ssd:ParameterBindings>",
        ]
    return "\n".join(lines + ["</ssd:Component>"])


def write_ssp(
    out: str | Path,
    name: str,
    fmus: Mapping[str, Path],
    connections: Sequence[tuple[str, str]],
    parameters: Mapping[str, Mapping[str, object]],
) -> Path:
    """Write the system as an SSP 1.0 file ``out`` (written whole or not at all); returns its path."""
    out, units = Path(out), dict[str, str]()
    elements = [
        _component(instance, Path(fmu), parameters.get(instance) or {}, units) for instance, fmu in fmus.items()
    ]
    links = []
    for source, target in connections:
        (a, b), (c, d) = source.split(".", 1), target.split(".", 1)
        links.append(
            f"<ssd:Connection startElement={quoteattr(a)} startConnector={quoteattr(b)} "
            f"endElement={quoteattr(c)} endConnector={quoteattr(d)}/>"
        )
    ssd = "\n".join(
        [
            '<?xml version="1.0" encoding="UTF-8"?>',
            '<ssd:SystemStructureDescription xmlns:ssc="http://ssp-standard.org/SSP1/SystemStructureCommon"'
            ' xmlns:ssd="http://ssp-standard.org/SSP1/SystemStructureDescription"'
            ' xmlns:ssv="http://ssp-standard.org/SSP1/SystemStructureParameterValues"'
            f' version="1.0" name={quoteattr(name)} generationTool="heliostep">',
            f"<ssd:System name={quoteattr(name)}>",
            "<ssd:Elements>",
            *elements,
            "</ssd:Elements>",
            *(["<ssd:Connections>", *links, "</ssd:Connections>"] if links else []),
            "</ssd:System>",
            *(["<ssd:Units>", *units.values(), "</ssd:Units>"] if units else []),
            "</ssd:SystemStructureDescription>",
            "",
        ]
    )
    out.parent.mkdir(parents=True, exist_ok=True)
    handle, partial = tempfile.mkstemp(dir=out.parent, prefix=f".{out.name}.")
    os.close(handle)
    try:
        with zipfile.ZipFile(partial, "w", zipfile.ZIP_DEFLATED) as archive:
            archive.writestr(zipfile.ZipInfo("SystemStructure.ssd", _FIXED_TIME), ssd, zipfile.ZIP_DEFLATED)
            for instance, fmu in fmus.items():
                entry = zipfile.ZipInfo(f"resources/{instance}.fmu", _FIXED_TIME)
                archive.writestr(entry, Path(fmu).read_bytes(), zipfile.ZIP_DEFLATED)
        publish(partial)  # private while written (mkstemp), the user's umask's mode once in place
        os.replace(partial, out)
    finally:
        if os.path.exists(partial):
            os.unlink(partial)
    return out
