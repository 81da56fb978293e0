"""Building the project's FMUs from ``models/``, cached by content, and ``heliostep build-fmus``.

Every ``models/NAME.mo`` becomes ``fmus/NAME.fmu`` through one loop (no per-model build
code). An FMU is rebuilt only when its *build key* changes: a SHA-256 of every Modelica
file of the folder, the FMI C layer, the build code and the versions of heliostep, pymoca,
CasADi, fmpy and the C compiler. The key also makes the FMU's GUID, so a built FMU says
which sources it came from. An ``.fmu`` in ``fmus/`` without a model of the same name
(for example one exported by another Modelica tool) is used as it is, never rebuilt.

The folders default to the ones of the source checkout (``models/`` and ``fmus/`` beside
``src/``); the environment variables ``HELIOSTEP_MODELS`` and ``HELIOSTEP_FMUS`` override
them.
"""

from __future__ import annotations

import argparse
import fcntl
import hashlib
import os
import re
import shutil
import subprocess
import tempfile
import uuid
import zipfile
from contextlib import contextmanager
from importlib import metadata, resources
from pathlib import Path

from heliostep import __version__
from heliostep.errors import InputError
from heliostep.fmu_export import FMI_LAYER, compiler, export_fmu
from heliostep.modelica import available_models, load_model, model_files

PROJECT_ROOT = Path(__file__).resolve().parents[2]
_GUID = re.compile(rb'\sguid="([^"]*)"')


def models_dir() -> Path:
    """The folder of Modelica models (``$HELIOSTEP_MODELS`` or the checkout's ``models/``)."""
    return Path(os.environ.get("HELIOSTEP_MODELS", PROJECT_ROOT / "models"))


def fmus_dir() -> Path:
    """The folder of FMUs (``$HELIOSTEP_FMUS`` or the checkout's ``fmus/``)."""
    return Path(os.environ.get("HELIOSTEP_FMUS", PROJECT_ROOT / "fmus"))


def _toolchain() -> list[str]:
    versions = [f"heliostep {__version__}"]
    for package in ("pymoca", "casadi", "fmpy"):
        versions.append(f"{package} {metadata.version(package)}")
    compiler_version = subprocess.run([compiler(), "--version"], capture_output=True, text=True)
    versions.append(compiler_version.stdout.splitlines()[0] if compiler_version.stdout else "cc ?")
    return versions


def build_key(model_name: str, models: Path) -> str:
    """SHA-256 of everything a built FMU depends on (see the module docstring)."""
    digest = hashlib.sha256()
    digest.update(model_name.encode())
    for path in model_files(models):
        digest.update(path.name.encode() + b"\0" + path.read_bytes() + b"\0")
    package = resources.files("heliostep")
    for name in ("c/" + FMI_LAYER, "fmu_export.py", "modelica.py"):
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


@contextmanager
def _lock(path: Path):
    """An exclusive lock on ``path`` (processes building the same FMU wait for each other)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "w") as handle:
        fcntl.flock(handle, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(handle, fcntl.LOCK_UN)


def build_fmu(model_name: str, out_dir: Path | None = None, models: Path | None = None,
              force: bool = False) -> Path:
    """Build ``out_dir/model_name.fmu`` from ``models/model_name.mo`` unless it is up to date."""
    models = Path(models or models_dir())
    out_dir = Path(out_dir or fmus_dir())
    if model_name not in available_models(models):
        raise InputError(f"{models}: no model {model_name!r}; available: "
                         f"{', '.join(available_models(models))}")
    key = build_key(model_name, models)
    guid = guid_of_key(key)
    fmu_path = out_dir / f"{model_name}.fmu"
    scratch = out_dir / ".build"
    with _lock(scratch / f"{model_name}.lock"):
        if not force and fmu_path.exists() and fmu_guid(fmu_path) == guid:
            return fmu_path
        model = load_model(models, model_name)
        work_dir = Path(tempfile.mkdtemp(prefix=f"{model_name}-", dir=scratch))
        try:
            tool = f"heliostep {__version__} (pymoca + CasADi); build key {key}"
            return export_fmu(model, fmu_path, guid, work_dir, tool)
        finally:
            shutil.rmtree(work_dir, ignore_errors=True)


def build_all(names: list[str] | None = None, out_dir: Path | None = None,
              models: Path | None = None, force: bool = False) -> list[Path]:
    """Build every model of the folder (or the ones named)."""
    models = Path(models or models_dir())
    return [build_fmu(name, out_dir, models, force) for name in names or available_models(models)]


def ensure_fmu(name_or_path: str | Path, fmus: Path | None = None, models: Path | None = None) -> Path:
    """The FMU for a variant name or a path, building it from ``models/`` when missing or stale.

    A path to an ``.fmu`` file is returned as it is (after checking it exists); a bare name
    is a model of ``models/`` (built into ``fmus/``) or else an FMU dropped into ``fmus/``.
    """
    fmus = Path(fmus or fmus_dir())
    models = Path(models or models_dir())
    text = str(name_or_path)
    if text.endswith(".fmu") or os.sep in text:
        path = Path(name_or_path)
        if not path.is_file():
            raise InputError(f"FMU file not found: {path}")
        return path
    if (models / f"{text}.mo").exists():
        return build_fmu(text, fmus, models)
    dropped = fmus / f"{text}.fmu"
    if dropped.is_file():
        return dropped
    known = sorted(set(available_models(models)) | {p.stem for p in fmus.glob("*.fmu")})
    raise InputError(f"unknown FMU variant {text!r}: neither {models}/{text}.mo nor "
                     f"{dropped} exists; known variants: {', '.join(known)}")


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        "build-fmus", help="compile the Modelica models to FMI 2.0 Model Exchange FMUs",
        description="Compile models/NAME.mo to fmus/NAME.fmu (pymoca -> CasADi -> C -> gcc). "
                    "Up-to-date FMUs are kept unless --force is given.")
    parser.add_argument("--model", action="append", metavar="NAME",
                        help="build only this model (repeatable); default: all models")
    parser.add_argument("--out", type=Path, metavar="DIR", help="output folder (default: fmus/)")
    parser.add_argument("--models", type=Path, metavar="DIR", help="Modelica folder (default: models/)")
    parser.add_argument("--force", action="store_true", help="rebuild even if up to date")
    parser.set_defaults(func=_run_build)


def _run_build(args: argparse.Namespace) -> int:
    for path in build_all(args.model, args.out, args.models, args.force):
        print(path)
    return 0
