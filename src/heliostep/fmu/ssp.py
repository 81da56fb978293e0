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
from heliostep.fmu.ssp_read import FMU_TYPE, NS
from heliostep.input_files import MAX_ARCHIVE_BYTES, read_input_bytes

__all__ = ["FMU_TYPE", "SSPSystem", "read_ssp", "write_ssp"]

_FIXED_TIME = (1980, 1, 1, 0, 0, 0)
#: FMI type -> SSP 1.0 connector type (FMI 3.0's types onto SSP's Real and Integer; an Enumeration,
#: which in SSP needs its type's name, as Integer); Real, Integer, Boolean, String and Binary as they are
_SSP_TYPES = {"Enumeration": "Integer", "Float64": "Real", "Float32": "Real"}
_SSP_TYPES.update({f"{sign}Int{bits}": "Integer" for sign in ("", "U") for bits in (8, 16, 32, 64)})


@dataclass
class SSPSystem:
    """What a scenario takes from an SSP: instance -> FMU file, connections, the transformations of
    connections (target -> (factor, offset)), instance -> parameters."""

    fmus: dict[str, Path] = field(default_factory=dict)
    connections: list[tuple[str, str]] = field(default_factory=list)
    parameters: dict[str, dict[str, object]] = field(default_factory=dict)
    transformations: dict[str, tuple[float, float]] = field(default_factory=dict)


def read_ssp(path: str | Path, cache: Path) -> SSPSystem:
    """The system of an SSP 1.0 file, flattened (:mod:`heliostep.fmu.ssp_read`, parameters
    :mod:`heliostep.fmu.ssp_values`), its FMUs extracted under ``cache``; InputError naming the file (and
    the element) otherwise."""
    from fmpy import read_model_description
    from fmpy.ssp.ssd import read_ssd

    from heliostep.fmu.ssp_read import Flattener
    from heliostep.fmu.ssp_values import Binder

    path = Path(path)
    if not path.exists():
        raise InputError(f"SSP file not found: {path}")
    digest = hashlib.sha256(read_input_bytes(path, "SSP", MAX_ARCHIVE_BYTES)).hexdigest()
    archive = _Archive(path)
    _check_sources(archive)
    try:
        ssd = read_ssd(str(path), validate=True)
    except Exception as exc:  # a schema violation (of the SSD or of an .ssv or .ssm it references)
        first = str(exc).strip().splitlines()
        raise InputError(f"{path}: not a valid SSP 1.0 file ({' '.join(first[:2]) or type(exc).__name__})") from None
    folder, names, described = Path(cache) / "ssp" / digest[:16], dict[str, str](), {}

    def describe(component: tuple[str, ...], member: str):
        if member not in described:
            name = Path(member).name if names.setdefault(Path(member).name, member) == member else None
            try:
                fmu = _extracted(path, ".".join(component), member, folder, name or member.replace("/", "_"))
            except OSError as exc:
                raise InputError(
                    f"{path}: component {'.'.join(component)!r}: cannot extract its FMU into the FMU cache {cache}"
                    f" ($HELIOSTEP_FMUS): {exc.strerror or exc}; point HELIOSTEP_FMUS at a writable folder"
                ) from None
            description = read_model_description(str(fmu), validate=False)
            described[member] = fmu, {v.name: v for v in description.modelVariables}, description.unitDefinitions
        return described[member][1:]

    flat = Flattener(path, ssd, archive.root, describe)
    parameters = Binder(flat, archive.xml, archive.validate).parameters()
    fmus = {name: described[member][0] for name, (_, member) in flat.result.components.items()}
    return SSPSystem(fmus, flat.result.connections, parameters, flat.result.transformations)


class _Archive:
    """The SSP's zip: its members' XML read (bounded, entities not resolved) and validated."""

    def __init__(self, path: Path):
        self.path = path
        try:
            with zipfile.ZipFile(path) as archive:
                self.members = set(archive.namelist())
            self.root = self.xml("SystemStructure.ssd", None)
        except (zipfile.BadZipFile, OSError, ValueError) as exc:
            raise InputError(f"{path}: not a valid SSP 1.0 file ({exc})") from None

    def xml(self, member: str, schema: str | None):
        """The root of the member's XML, validated against ``schema`` (an SSP 1.0 schema fmpy ships)."""
        from lxml import etree

        if member not in self.members:
            raise InputError(f"{self.path}: {member!r} is not in the file")
        with zipfile.ZipFile(self.path) as archive:
            if archive.getinfo(member).file_size > MAX_ARCHIVE_BYTES:
                raise InputError(f"{self.path}: {member!r} unpacks to more than an SSP's part may be")
            data = archive.read(member)
        parser = etree.XMLParser(resolve_entities=False, no_network=True, huge_tree=False)
        try:
            root = etree.fromstring(data, parser)
        except etree.XMLSyntaxError as exc:
            raise InputError(f"{self.path}: {member}: not well-formed XML ({exc})") from None
        if schema is not None:
            self.validate(root, schema, member)
        return root

    def validate(self, element, schema: str, member: str = "SystemStructure.ssd") -> None:
        from fmpy.ssp.ssd import validate_tree

        try:
            validate_tree(element, schema)
        except Exception as exc:
            lines = str(exc).strip().splitlines()[1:3]
            raise InputError(f"{self.path}: {member}: not valid against {schema} ({' '.join(lines)})") from None


def _check_sources(archive: _Archive) -> None:
    """Every parameter binding's and mapping's source is a member of the archive, relative to the SSD."""
    for tag in ("ssd:ParameterBinding", "ssd:ParameterMapping"):
        for element in archive.root.iter(f"{{{NS['ssd']}}}{tag.split(':')[1]}"):
            source = element.get("source")
            owner = element.getparent()
            while owner is not None and owner.tag.split("}")[1] not in ("Component", "System"):
                owner = owner.getparent()
            named = f"ssd:{owner.tag.split('}')[1]} {owner.get('name')!r}" if owner is not None else "the system"
            where = f"{archive.path}: {tag} of {named}"
            if element.get("sourceBase") == "component":
                raise InputError(f'{where}: sourceBase="component" (a source inside the FMU) is not supported')
            if source is not None and source not in archive.members:
                raise InputError(f"{where}: its source {source!r} is not in the file (only sources in it are read)")


def _extracted(path: Path, name: str, member: str, folder: Path, file_name: str) -> Path:
    """The component's FMU (archive ``member``) extracted into ``folder/file_name`` (reused when there, whole)."""
    with zipfile.ZipFile(path) as archive:
        if member not in archive.namelist():
            raise InputError(f"{path}: ssd:Component {name!r}: its source {member!r} is not in the file")
        if archive.getinfo(member).file_size > MAX_ARCHIVE_BYTES:
            raise InputError(f"{path}: ssd:Component {name!r}: its source {member!r} unpacks to more than an FMU can")
        data = archive.read(member)
    target = folder / file_name
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


def _connection(source: str, target: str, transform: tuple[float, float] | None) -> str:
    """An SSD ``Connection``; with a (factor, offset), its ``ssc:LinearTransformation`` (and no unit conversion)."""
    (a, b), (c, d) = source.split(".", 1), target.split(".", 1)
    ends = (
        f"<ssd:Connection startElement={quoteattr(a)} startConnector={quoteattr(b)} "
        f"endElement={quoteattr(c)} endConnector={quoteattr(d)}"
    )
    if transform is None:
        return f"{ends}/>"
    return (
        f'{ends} suppressUnitConversion="true"><ssc:LinearTransformation factor="{transform[0]!r}"'
        f' offset="{transform[1]!r}"/></ssd:Connection>'
    )


def write_ssp(
    out: str | Path,
    name: str,
    fmus: Mapping[str, Path],
    connections: Sequence[tuple[str, str]],
    parameters: Mapping[str, Mapping[str, object]],
    transformations: Mapping[str, tuple[float, float]] | None = None,
) -> Path:
    """Write the system as an SSP 1.0 file ``out`` (written whole or not at all); returns its path. A connection
    whose target has a (factor, offset) in ``transformations`` carries it as its ``ssc:LinearTransformation``,
    with ``suppressUnitConversion`` (the transformation is the whole conversion)."""
    out, units = Path(out), dict[str, str]()
    elements = [
        _component(instance, Path(fmu), parameters.get(instance) or {}, units) for instance, fmu in fmus.items()
    ]
    links = [_connection(source, target, (transformations or {}).get(target)) for source, target in connections]
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
