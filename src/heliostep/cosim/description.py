"""What heliostep reads of an FMU before running it: ``modelDescription.xml`` and its binary.

:func:`read_fmu` checks the FMU (its kind, :mod:`~heliostep.cosim.kinds`; a binary for this platform
exporting the kind's functions) and returns an :class:`FMUInfo` with every variable and its type;
:func:`convert_value` turns a value given by the user into a variable's type.
"""

from __future__ import annotations

import atexit
import math
import shutil
import tempfile
import zipfile
import zlib
from dataclasses import dataclass, field
from pathlib import Path

from heliostep.cosim.archive import DEFAULT_MAX_UNPACKED_BYTES, check_fmu_archive, remove_unpacked, unpack
from heliostep.cosim.elf import NotASharedObject, read_shared_object
from heliostep.cosim.fmi3_types import integer_range
from heliostep.cosim.kinds import Kind, kind_of, versions
from heliostep.cosim.structure import check_model_structure
from heliostep.errors import InputError, RunFailure


@dataclass(frozen=True)
class VariableInfo:
    """What the master needs to know of one scalar variable."""

    name: str
    value_reference: int
    type: str
    causality: str
    variability: str
    unit: str = ""
    start: float | str | None = None  # float for Real/Integer/Boolean/Enumeration, str for String
    description: str = ""
    #: FMI 3.0 only (:mod:`heliostep.cosim.fmi3_types`): the variable's FMI 3.0 type, its FMI 3.0
    #: value reference, its element (row-major, 0-based; -1: a scalar) and the array's number of elements
    fmi3_type: str = ""
    fmi3_reference: int = -1
    element: int = -1
    size: int = 1

    @property
    def discrete(self) -> bool:
        """Changes only at events: every non-float variable, and float ones of variability discrete."""
        return self.type not in ("Real", "Float32") or self.variability != "continuous"

    @property
    def through_slot(self) -> bool:
        """An FMI 3.0 variable the fmi2-shaped calls reach through the adapter's slot table (every
        array element, every scalar but Float64, Int32 and Boolean): read and set as a double there."""
        return bool(self.fmi3_type) and self.value_reference != self.fmi3_reference

    @property
    def exchanged_as_real(self) -> bool:
        """Read and set as a double by the compiled kernel (FMI 2.0 Real, FMI 3.0 Float64 and Float32)."""
        return self.type in ("Real", "Float32")


@dataclass
class FMUInfo:
    """The parts of an FMU's modelDescription.xml that heliostep uses."""

    path: Path
    model_name: str
    model_identifier: str
    guid: str
    variables: dict[str, VariableInfo]
    states: list[str]
    n_event_indicators: int
    #: output name -> names of the inputs it depends on directly (direct feedthrough)
    output_feedthrough: dict[str, list[str]] = field(default_factory=dict)
    #: whether fmi2CompletedIntegratorStep must be called after each integrator step
    needs_completed_integrator_step: bool = True
    description: object = None  # fmpy's ModelDescription
    #: read for Co-Simulation (a sampled component) rather than Model Exchange
    co_simulation: bool = False
    #: modelDescription.xml's fmiVersion
    fmi_version: str = "2.0"

    @property
    def kind(self) -> Kind:
        """The FMU's kind (version and interface, :mod:`~heliostep.cosim.kinds`)."""
        kind = kind_of(self.fmi_version, self.co_simulation)
        assert kind is not None, "read_fmu refuses the kinds heliostep does not run"
        return kind

    def names(self, causality: str) -> list[str]:
        return [v.name for v in self.variables.values() if v.causality == causality]

    @property
    def inputs(self) -> list[str]:
        return self.names("input")

    @property
    def outputs(self) -> list[str]:
        return self.names("output")

    @property
    def traced_outputs(self) -> list[str]:
        """Outputs that go into the trace (as floats): every type but String (and FMI 3's Binary)."""
        return [name for name in self.outputs if self.variables[name].type not in ("String", "Binary")]

    @property
    def parameters(self) -> list[str]:
        return self.names("parameter")

    @property
    def default_step(self) -> float | None:
        """The communication step the FMU suggests [s] (its DefaultExperiment ``stepSize``); None where it
        gives no positive finite one."""
        return default_step(self.description)

    def variable(self, name: str) -> VariableInfo:
        try:
            return self.variables[name]
        except KeyError:
            raise InputError(
                f"{self.path}: no variable {name!r} in {self.model_name}; variables: {', '.join(self.variables)}"
            ) from None


def _unit(variable) -> str:
    if variable.unit:
        return variable.unit
    declared = getattr(variable, "declaredType", None)
    return getattr(declared, "unit", None) or ""


def default_step(description: object) -> float | None:
    """The DefaultExperiment ``stepSize`` [s] of fmpy's model ``description``, where positive and finite."""
    text = getattr(getattr(description, "defaultExperiment", None), "stepSize", None)
    try:
        step = float(text) if text is not None else math.nan
    except ValueError:
        return None
    return step if math.isfinite(step) and step > 0 else None


def read_fmu(
    path: str | Path, co_simulation: bool | None = False, max_unpacked_bytes: int = DEFAULT_MAX_UNPACKED_BYTES
) -> FMUInfo:
    """Read and check an FMU of a kind heliostep runs (FMI 2.0 or 3.0): Model Exchange, or with
    ``co_simulation`` Co-Simulation (a sampled component, :mod:`heliostep.cosim.sampled`); else
    :class:`InputError`. ``co_simulation=None``: as the FMU offers, Model Exchange where it has it, else
    Co-Simulation where it suggests a step (its :attr:`FMUInfo.default_step`). Its archive is checked first
    (:func:`~heliostep.cosim.archive.check_fmu_archive`: entry names, at most ``max_unpacked_bytes`` unpacked)."""
    from fmpy import read_model_description

    path = Path(path)
    if not path.exists():
        raise InputError(f"FMU file not found: {path}")
    check_fmu_archive(path, max_unpacked_bytes)
    try:
        description = read_model_description(str(path), validate=False)
    except Exception as exc:
        raise InputError(f"{path}: not a readable FMU ({exc})") from None
    if co_simulation is None:
        co_simulation = getattr(description, "modelExchange", None) is None and default_step(description) is not None
    kind = kind_of(description.fmiVersion, co_simulation)
    if kind is None:
        raise InputError(f"{path}: FMI version {description.fmiVersion}; heliostep needs FMI {versions()}")
    check_model_structure(path, description)
    return kind.read(path, description)


def read_fmi2(path: Path, description, kind: Kind) -> FMUInfo:
    """An FMI 2.0 FMU read by fmpy (``description``) as the master's :class:`FMUInfo` of ``kind``."""
    interface = description.coSimulation if kind.co_simulation else description.modelExchange
    if interface is None and kind.co_simulation:
        raise InputError(f"{path}: the FMU does not support Co-Simulation, but communication_interval asks for it")
    if interface is None:
        raise InputError(
            f"{path}: the FMU does not support Model Exchange (co-simulation only); heliostep integrates Model "
            "Exchange FMUs itself, or runs a Co-Simulation FMU as a sampled component: give its instance a "
            "communication_interval (docs/fmus.md)"
        )
    check_binary(path, interface.modelIdentifier, kind)
    variables = _variables(description)
    states = [d.variable.derivative.name for d in description.derivatives]
    inputs = {v.name for v in description.modelVariables if v.causality == "input"}
    feedthrough = {}
    for unknown in description.outputs:
        dependencies = unknown.dependencies
        if dependencies is None:  # no dependency information: depends on every input
            names = sorted(inputs)
        else:
            names = [d.name for d in dependencies if d.name in inputs]
        feedthrough[unknown.variable.name] = names
    return FMUInfo(
        path=path,
        model_name=description.modelName,
        model_identifier=interface.modelIdentifier,
        guid=description.guid,
        variables=variables,
        states=states,
        n_event_indicators=description.numberOfEventIndicators or 0,
        output_feedthrough=feedthrough,
        description=description,
        needs_completed_integrator_step=bool(getattr(interface, "needsCompletedIntegratorStep", False)),
        co_simulation=kind.co_simulation,
        fmi_version=kind.version,
    )


def _variables(description) -> dict[str, VariableInfo]:
    """Name -> what the master needs of each variable of fmpy's ``ModelDescription``."""
    return {
        v.name: VariableInfo(
            name=v.name,
            value_reference=v.valueReference,
            type=v.type,
            causality=v.causality,
            variability=v.variability,
            unit=_unit(v),
            start=None if v.start is None else _parse_start(v.type, v.start),
            description=v.description or "",
        )
        for v in description.modelVariables
    }


def _parse_start(type_: str, start) -> float | str | None:
    if type_ == "String":
        return str(start)
    if type_ == "Boolean":
        return float(str(start).strip().lower() in ("true", "1"))
    try:
        return float(start)
    except (TypeError, ValueError):
        return None


def check_binary(path: Path, model_identifier: str, kind: Kind, platform: str | None = None) -> None:
    """The FMU must have a binary for this platform, a shared object for this machine that exports ``kind``'s
    required functions (read from the file: loading it would run its code in this process).

    Refused with :class:`InputError` naming the ``.fmu`` file and the platform (never the
    temporary folder it is unpacked to).
    """
    import fmpy

    platform = platform or fmpy.platform
    sharedLibraryExtension = fmpy.sharedLibraryExtension
    member = f"binaries/{platform}/{model_identifier}{sharedLibraryExtension}"
    with zipfile.ZipFile(path) as archive:
        names = archive.namelist()
    if member not in names:
        available = sorted(
            {n.split("/")[1] for n in names if n.startswith("binaries/") and n.count("/") >= 2 and n.split("/")[1]}
        )
        raise InputError(
            f"{path}: no binary for this platform ({platform}): {member} is missing; "
            f"the FMU has binaries for: {', '.join(available) or 'no platform'}"
        )
    if not member.endswith(".so"):  # not an ELF file: read when the supervised child loads it
        return
    library = Path(_extract(path)) / member
    try:  # read, never loaded here: its code (constructors too) runs in the supervised child only
        exported = read_shared_object(library)
    except NotASharedObject as exc:
        raise InputError(f"{path}: the binary for {platform} ({member}) does not load: it is {exc}") from None
    missing = [name for name in kind.required_functions if name not in exported]
    if missing:
        raise InputError(
            f"{path}: the binary for {platform} ({member}) lacks the FMI {kind.version} {kind.interface} function(s) "
            f"{', '.join(missing)}"
        )


_extracted: dict[tuple[str, float], str] = {}
_extract_root = None


def _extract(path: Path) -> str:
    """Unzip an FMU once per process (per file and modification time), each entry no longer than it
    declares (:func:`~heliostep.cosim.archive.unpack`)."""
    global _extract_root

    key = (str(path.resolve()), path.stat().st_mtime)
    if key not in _extracted:
        if _extract_root is None:
            _extract_root = tempfile.mkdtemp(prefix="heliostep-fmus-")
            atexit.register(shutil.rmtree, _extract_root, True)
        folder = tempfile.mkdtemp(dir=_extract_root)
        try:
            unpack(path, Path(folder))
        except (zipfile.BadZipFile, zlib.error, EOFError) as exc:  # a damaged archive (a flipped bit, cut short)
            remove_unpacked(Path(folder))
            raise InputError(f"{path}: a damaged FMU archive ({type(exc).__name__}: {exc})") from None
        except OSError as exc:  # the temporary folder is full or read-only: named, it is not --out
            remove_unpacked(Path(folder))
            raise RunFailure(
                f"{path}: could not be unpacked into {_extract_root} (the temporary folder, TMPDIR): "
                f"{exc.strerror or exc}"
            ) from None
        except BaseException:
            remove_unpacked(Path(folder))
            raise
        _extracted[key] = folder
    return _extracted[key]


def convert_value(variable: VariableInfo, value):
    """A scenario value converted to the variable's type (InputError when it does not fit):
    Real from numbers, Integer/Enumeration (and FMI 3.0's Int8 ... UInt64) from whole numbers in the
    type's range, Boolean from True/False, 0/1 or "true"/"false", Binary from bytes or hexadecimal
    digits, String from anything."""
    try:
        if variable.type in ("Real", "Float32"):
            return float(value)
        if variable.type in ("Integer", "Enumeration") or variable.type.lstrip("U").startswith("Int"):
            if isinstance(value, bool) or float(value) != int(float(value)):
                raise ValueError
            whole, limits = int(value) if isinstance(value, int) else int(float(value)), integer_range(variable)
            if limits is not None and not limits[0] <= whole <= limits[1]:
                raise ValueError
            return whole
        if variable.type == "Boolean":
            if isinstance(value, str):
                if value.strip().lower() not in ("true", "false", "1", "0"):
                    raise ValueError
                return value.strip().lower() in ("true", "1")
            if value not in (0, 1, True, False):
                raise ValueError
            return bool(value)
        if variable.type == "Binary":  # bytes, or their hexadecimal digits
            return bytes(value) if isinstance(value, (bytes, bytearray)) else bytes.fromhex(str(value))
        return str(value)
    except (TypeError, ValueError):
        raise InputError(f"parameter {variable.name}: {value!r} is not a valid {variable.type} value") from None
