"""Building the project's FMUs from the Modelica models, cached by content.

Every ``models/NAME.mo`` becomes ``NAME.fmu`` in the FMU cache through one loop (no per-model build
code). An FMU is rebuilt only when its *build key* changes: a SHA-256 of every Modelica
file of the folder, the FMI C layer, the build code and the versions of heliostep, pymoca,
CasADi, fmpy and the C compiler. The key also makes the FMU's GUID, so a built FMU says
which sources it came from. An ``.fmu`` a user drops into an ``fmus/`` folder (beside the
scenario, or in the current directory) without a model of the same name (for example one
exported by another Modelica tool) is used as it is, never rebuilt.

Folders: :mod:`heliostep.paths` (shipped models; the per-user FMU cache, or
``$HELIOSTEP_MODELS`` / ``$HELIOSTEP_FMUS``).
"""

from __future__ import annotations

import hashlib
import re
import shutil
import tempfile
import uuid
import zipfile
from importlib import metadata, resources
from pathlib import Path

from heliostep._version import __version__
from heliostep.errors import InputError
from heliostep.fmu.export import FMI_LAYER, compiler, export_fmu
from heliostep.fmu.modelica import available_models, load_model, model_files
from heliostep.fmu.reference import is_variant_name
from heliostep.paths import fmus_dir, models_dir
from heliostep.toolchain import compiler_version, exclusive_lock

_GUID = re.compile(rb'\sguid="([^"]*)"')


def _toolchain() -> list[str]:
    versions = [f"heliostep {__version__}"]
    for package in ("pymoca", "casadi", "fmpy"):
        versions.append(f"{package} {metadata.version(package)}")
    versions.append(compiler_version(compiler()))
    return versions


def build_key(model_name: str, models: Path) -> str:
    """SHA-256 of everything a built FMU depends on (see the module docstring)."""
    digest = hashlib.sha256()
    digest.update(model_name.encode())
    for path in model_files(models):
        digest.update(path.name.encode() + b"\0" + path.read_bytes() + b"\0")
    package = resources.files("heliostep.fmu")
    for name in ("c/" + FMI_LAYER, "export.py", "model_xml.py", "modelica.py"):
        digest.update((package / name).read_bytes())
    for line in _toolchain():
        digest.update(line.encode() + b"\0")
    return digest.hexdigest()


def guid_of_key(key: str) -> str:
    return "{" + str(uuid.UUID(hex=key[:32])) + "}"


def fmu_guid(path: Path) -> str | None:
    """The GUID in an FMU's modelDescription.xml, or None if it cannot be read."""
    try:
        with zipfile.ZipFile(path) as archive:
            match = _GUID.search(archive.read("modelDescription.xml"))
    except (OSError, KeyError, zipfile.BadZipFile):
        return None
    return match.group(1).decode() if match else None


def build_fmu(model_name: str, out_dir: Path | None = None, models: Path | None = None, force: bool = False) -> Path:
    """Build ``out_dir/model_name.fmu`` from ``models/model_name.mo`` unless it is up to date."""
    models = Path(models or models_dir())
    out_dir = Path(out_dir or fmus_dir())
    if model_name not in available_models(models):
        raise InputError(f"{models}: no model {model_name!r}; available: {', '.join(available_models(models))}")
    key = build_key(model_name, models)
    guid = guid_of_key(key)
    fmu_path = out_dir / f"{model_name}.fmu"
    scratch = out_dir / ".build"
    with exclusive_lock(scratch / f"{model_name}.lock"):
        if not force and fmu_path.exists() and fmu_guid(fmu_path) == guid:
            return fmu_path
        model = load_model(models, model_name)
        work_dir = Path(tempfile.mkdtemp(prefix=f"{model_name}-", dir=scratch))
        try:
            tool = f"heliostep {__version__} (pymoca + CasADi); build key {key}"
            return export_fmu(model, fmu_path, guid, work_dir, tool)
        finally:
            shutil.rmtree(work_dir, ignore_errors=True)


def build_all(
    names: list[str] | None = None, out_dir: Path | None = None, models: Path | None = None, force: bool = False
) -> list[Path]:
    """Build every model of the folder (or the ones named)."""
    models = Path(models or models_dir())
    return [build_fmu(name, out_dir, models, force) for name in names or available_models(models)]


def ensure_fmu(
    name_or_path: str | Path, search: tuple[Path, ...] = (), fmus: Path | None = None, models: Path | None = None
) -> Path:
    """The FMU for a variant name or a path, building it from the models when missing or stale.

    A path to an ``.fmu`` file is returned as it is (after checking it exists). A bare name
    is, in this order: a model of the models folder (built into the FMU cache), an FMU
    dropped into one of the ``search`` folders (e.g. ``fmus/`` beside the scenario and in the
    current directory), or one in the FMU cache folder.
    """
    fmus = Path(fmus or fmus_dir())
    models = Path(models or models_dir())
    text = str(name_or_path)
    if not is_variant_name(text):
        path = Path(name_or_path)
        if not path.is_file():
            raise InputError(f"FMU file not found: {path}")
        return path
    if (models / f"{text}.mo").exists():
        return build_fmu(text, fmus, models)
    folders = [*search, fmus]
    for folder in folders:
        dropped = Path(folder) / f"{text}.fmu"
        if dropped.is_file():
            return dropped
    known = sorted(set(available_models(models)) | {p.stem for f in folders for p in Path(f).glob("*.fmu")})
    looked = ", ".join(str(Path(f) / f"{text}.fmu") for f in folders)
    raise InputError(
        f"unknown FMU variant {text!r}: neither {models}/{text}.mo nor any of {looked} "
        f"exists; known variants: {', '.join(known)}"
    )
