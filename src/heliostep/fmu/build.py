"""Building the project's FMUs from the Modelica models, cached by content.

Every ``models/NAME.mo`` becomes an FMU through one loop, rebuilt only when its build key (a hash of
the sources, the FMI version and the tools' versions) changes.

Details: docs/fmus.md, ``heliostep.fmu.build``.
"""

from __future__ import annotations

import hashlib
import os
import re
import shutil
import tempfile
import uuid
import zipfile
from collections.abc import Iterator
from contextlib import contextmanager
from importlib import metadata, resources
from pathlib import Path

from heliostep._version import __version__
from heliostep.errors import InputError
from heliostep.fmu.export import FMI_LAYERS, LAYER_CORE, compiler, export_fmu
from heliostep.fmu.modelica import available_models, load_model, model_files
from heliostep.fmu.reference import is_variant_name
from heliostep.paths import fmus_dir, models_dir, private_cache
from heliostep.progress import note
from heliostep.toolchain import compiler_version, exclusive_lock

#: A variant name ``NAME-fmi3`` is model ``NAME`` built as an FMI 3.0 FMU (:func:`ensure_fmu`).
FMI3_SUFFIX = "-fmi3"
_GUID = re.compile(rb'\s(?:guid|instantiationToken)="([^"]*)"')


def _toolchain() -> list[str]:
    versions = [f"heliostep {__version__}"]
    for package in ("pymoca", "casadi", "fmpy"):
        versions.append(f"{package} {metadata.version(package)}")
    versions.append(compiler_version(compiler()))
    return versions


def _check_version(fmi_version: int) -> None:
    if fmi_version not in FMI_LAYERS:
        raise InputError(f"FMI version {fmi_version!r}: expected one of {', '.join(map(str, FMI_LAYERS))}")


def build_key(model_name: str, models: Path, fmi_version: int = 2) -> str:
    """SHA-256 of everything a built FMU depends on (see the module docstring)."""
    _check_version(fmi_version)
    digest = hashlib.sha256()
    digest.update(model_name.encode())
    if fmi_version != 2:  # FMI 2.0 keys carry no version, so its cached FMUs keep their keys and GUIDs
        digest.update(f"fmi{fmi_version}\0".encode())
    for path in model_files(models):
        digest.update(path.name.encode() + b"\0" + path.read_bytes() + b"\0")
    package = resources.files("heliostep.fmu")
    for name in ("c/" + FMI_LAYERS[fmi_version], "c/" + LAYER_CORE, "export.py", "model_xml.py", "modelica.py"):
        digest.update((package / name).read_bytes())
    for line in _toolchain():
        digest.update(line.encode() + b"\0")
    return digest.hexdigest()


def guid_of_key(key: str) -> str:
    return "{" + str(uuid.UUID(hex=key[:32])) + "}"


def fmu_guid(path: Path) -> str | None:
    """The GUID (FMI 3.0: instantiation token) in an FMU's modelDescription.xml, or None if it cannot be read."""
    try:
        with zipfile.ZipFile(path) as archive:
            match = _GUID.search(archive.read("modelDescription.xml"))
    except (OSError, KeyError, zipfile.BadZipFile):
        return None
    return match.group(1).decode() if match else None


def cached_fmu_path(model_name: str, key: str, cache: Path, fmi_version: int = 2) -> Path:
    """Where the FMU of ``model_name`` with build ``key`` lives in ``cache`` (``NAME.fmu`` for FMI 2.0,
    ``NAME-fmi3.fmu`` for FMI 3.0, so that both can be copied to one folder)."""
    return cache / key[:16] / (f"{model_name}.fmu" if fmi_version == 2 else f"{model_name}{FMI3_SUFFIX}.fmu")


def digest_path(fmu_path: Path) -> Path:
    """The file holding the SHA-256 of ``fmu_path`` recorded when it was built."""
    return fmu_path.with_name(fmu_path.name + ".sha256")


def file_sha256(path: Path) -> str:
    """The SHA-256 of a file's bytes (hex)."""
    digest = hashlib.sha256()
    with open(path, "rb") as handle:
        for chunk in iter(lambda: handle.read(1 << 20), b""):
            digest.update(chunk)
    return digest.hexdigest()


def verified(fmu_path: Path) -> bool:
    """True when ``fmu_path`` and its recorded digest exist and the file's SHA-256 matches it."""
    try:
        recorded = digest_path(fmu_path).read_text().strip()
        return bool(recorded) and file_sha256(fmu_path) == recorded
    except OSError:
        return False


def build_fmu(
    model_name: str, out_dir: Path | None = None, models: Path | None = None, force: bool = False, fmi_version: int = 2
) -> Path:
    """The FMI ``fmi_version`` (2 or 3) FMU of ``models/model_name.mo`` in the cache ``out_dir``
    (:func:`cached_fmu_path`), built unless a verified one with the same build key is there (see
    the module docstring)."""
    models = Path(models or models_dir())
    out_dir = private_cache(Path(out_dir)) if out_dir else fmus_dir()
    _check_version(fmi_version)
    if model_name not in available_models(models):
        raise InputError(f"{models}: no model {model_name!r}; available: {', '.join(available_models(models))}")
    key = build_key(model_name, models, fmi_version)
    fmu_path = cached_fmu_path(model_name, key, out_dir, fmi_version)
    if not force and verified(fmu_path):  # up to date: no lock, nothing written
        return fmu_path
    scratch = out_dir / ".build"
    with _build_lock(scratch, model_name):
        if not force and verified(fmu_path):  # built by another process meanwhile
            return fmu_path
        _clear_dead_builds(scratch, model_name)
        why = "--force" if force else "first use" if not fmu_path.exists() else "the cached copy failed its check"
        note(f"heliostep: building {fmu_path.name} ({why}, cached in {out_dir})")  # a build takes seconds
        return _build(model_name, models, key, fmu_path, scratch, fmi_version)


@contextmanager
def _build_lock(scratch: Path, model_name: str) -> Iterator[None]:
    """The model's build lock in the cache; InputError naming the cache when it cannot be taken."""
    try:
        lock = exclusive_lock(scratch / f"{model_name}.lock")
        lock.__enter__()
    except OSError as exc:
        raise InputError(
            f"FMU cache {scratch.parent} ($HELIOSTEP_FMUS): cannot build {model_name}.fmu there "
            f"({exc.strerror or exc}); point HELIOSTEP_FMUS at a writable folder"
        ) from None
    try:
        yield
    finally:
        lock.__exit__(None, None, None)


def _build(model_name: str, models: Path, key: str, fmu_path: Path, scratch: Path, fmi_version: int) -> Path:
    """Export the model to ``fmu_path`` (its digest recorded beside it), working in ``scratch``."""
    model = load_model(models, model_name)
    work_dir = Path(tempfile.mkdtemp(prefix=f"{model_name}-{os.getpid()}-", dir=scratch))
    try:
        fmu_path.parent.mkdir(parents=True, exist_ok=True)
        tool = f"heliostep {__version__} (pymoca + CasADi); build key {key}"
        export_fmu(model, fmu_path, guid_of_key(key), work_dir, tool, fmi_version)
        record = work_dir / "digest"
        record.write_text(file_sha256(fmu_path) + "\n")
        record.replace(digest_path(fmu_path))  # the FMU counts as built once this is in place
        return fmu_path
    finally:
        shutil.rmtree(work_dir, ignore_errors=True)


def _clear_dead_builds(scratch: Path, model_name: str) -> None:
    """Remove the work folders ``scratch/model_name-PID-*`` of builds whose process is gone (a
    build killed midway); called with the model's lock held."""
    for folder in scratch.glob(f"{model_name}-*"):
        owner = folder.name[len(model_name) + 1 :].split("-")[0]
        if folder.is_dir() and not (owner.isdigit() and _alive(int(owner))):
            shutil.rmtree(folder, ignore_errors=True)


def _alive(pid: int) -> bool:
    if pid == os.getpid():
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # another user's live process
        return True
    return True


def build_all(
    names: list[str] | None = None,
    out_dir: Path | None = None,
    models: Path | None = None,
    force: bool = False,
    fmi_version: int = 2,
) -> list[Path]:
    """Build every model of the folder (or the ones named) as FMI ``fmi_version`` FMUs."""
    models = Path(models or models_dir())
    return [build_fmu(name, out_dir, models, force, fmi_version) for name in names or available_models(models)]


def copy_fmu(fmu_path: Path, out_dir: Path) -> Path:
    """A copy of a built FMU as ``out_dir/NAME.fmu`` (written whole or not at all), e.g. to drop
    into a scenario's ``fmus/`` folder or to give to another tool."""
    out_dir.mkdir(parents=True, exist_ok=True)
    target = out_dir / fmu_path.name
    partial = out_dir / f".{fmu_path.name}.{os.getpid()}.tmp"
    try:
        shutil.copyfile(fmu_path, partial)
        partial.replace(target)
    finally:
        partial.unlink(missing_ok=True)
    return target


def ensure_fmu(
    name_or_path: str | Path, beside: Path | None = None, fmus: Path | None = None, models: Path | None = None
) -> Path:
    """The FMU for a variant name or a path, building it from the models when missing or stale.

    A path to an ``.fmu`` file is returned as it is (after checking it exists). A bare name is looked up
    in the folders of :func:`variant_folders`, in their order: a model ``NAME.mo`` of a models folder
    (built into the FMU cache; ``NAME-fmi3``: model ``NAME`` as an FMI 3.0 FMU), else an FMU ``NAME.fmu``
    of an FMU folder. ``beside``: the scenario's folder, whose ``models/`` and ``fmus/`` come first.
    """
    fmus = Path(fmus or fmus_dir())
    text = str(name_or_path)
    if not is_variant_name(text):
        path = Path(name_or_path)
        if not path.is_file():
            raise InputError(f"FMU file not found: {path}")
        return path
    model_folders, fmu_folders = variant_folders(beside, fmus, models)
    base, fmi_version = (text[: -len(FMI3_SUFFIX)], 3) if text.endswith(FMI3_SUFFIX) else (text, 2)
    for folder in model_folders:
        if (folder / f"{text}.mo").exists():
            return build_fmu(text, fmus, folder)
        if fmi_version == 3 and (folder / f"{base}.mo").exists():
            return build_fmu(base, fmus, folder, fmi_version=3)
    for folder in fmu_folders:
        if (folder / f"{text}.fmu").is_file():
            return folder / f"{text}.fmu"
    raise InputError(_unknown_variant(text, model_folders, fmu_folders))


def variant_folders(
    beside: Path | None = None, fmus: Path | None = None, models: Path | None = None
) -> tuple[list[Path], list[Path]]:
    """Where a bare variant name is looked for, each folder once, in order: the models folders
    (``beside/models``, then ``models``: default ``$HELIOSTEP_MODELS`` or the shipped models) and the FMU
    folders (``beside/fmus``, the current folder's ``fmus``, then the FMU cache ``fmus``)."""
    local = [] if beside is None else [Path(beside) / "models"]
    dropped = [] if beside is None else [Path(beside) / "fmus", Path.cwd() / "fmus"]
    return _once([*local, Path(models or models_dir())]), _once([*dropped, Path(fmus or fmus_dir())])


def _once(folders: list[Path]) -> list[Path]:
    """``folders`` without a repeat of one already listed (the same folder by another path included)."""
    seen: dict[Path, Path] = {}
    for folder in folders:
        seen.setdefault(folder.resolve(), folder)
    return list(seen.values())


def _unknown_variant(text: str, model_folders: list[Path], fmu_folders: list[Path]) -> str:
    """Why ``text`` names no variant: every path looked at (once), the variants there are, and how to add one."""
    known = {p.stem for folder in model_folders for p in folder.glob("*.mo")}
    known |= {p.stem for folder in fmu_folders for p in folder.glob("*.fmu")}
    looked = [*(folder / f"{text}.mo" for folder in model_folders), *(folder / f"{text}.fmu" for folder in fmu_folders)]
    return (
        f"unknown FMU variant {text!r}: none of {', '.join(map(str, looked))} exists; known variants: "
        f"{', '.join(sorted(known)) or 'none'}. A model is a NAME.mo in one of those models folders (built on "
        f"first use, or ahead with `heliostep build-fmus --models DIR --model NAME`); an FMU is a NAME.fmu in one "
        f"of those fmus folders"
    )
