"""Source FMUs: an FMU that ships only ``sources/`` compiled on first use, cached by content.

Compiled with the project's one toolchain into a cached copy of the FMU that adds this platform's binary.

Details: docs/fmus.md, ``heliostep.fmu.sources``.
"""

from __future__ import annotations

import hashlib
import os
import re
import shutil
import subprocess
import tempfile
import zipfile
import zlib
from dataclasses import dataclass
from importlib import metadata, resources
from pathlib import Path

from heliostep.errors import InputError
from heliostep.fmu.build import digest_path, file_sha256, verified
from heliostep.fmu.export import compiler
from heliostep.input_files import MAX_ARCHIVE_BYTES, read_input_bytes
from heliostep.paths import private_cache
from heliostep.toolchain import compiler_version, exclusive_lock

__all__ = ["SOURCE_CACHE", "source_build_key", "with_platform_binary"]

#: The folder of the FMU cache that holds compiled source FMUs.
SOURCE_CACHE = "sources"
_FIXED_TIME = (1980, 1, 1, 0, 0, 0)  # zip entries' time stamps: the copy is the same bytes every time


@dataclass(frozen=True)
class _SourceBuild:
    """What to compile of a source FMU: per model identifier its source files and flags, and the
    platform folder its binaries go to."""

    platform: str
    #: modelIdentifier -> (source files relative to sources/, -D and -I flags)
    libraries: dict[str, tuple[list[str], list[str]]]


def _platforms() -> tuple[str, str]:
    """The platform folders of this machine: FMI 2.0's (``linux64``) and FMI 3.0's (``x86_64-linux``)."""
    from fmpy import platform, platform_tuple

    return platform, platform_tuple


def _source_build(path: Path, names: list[str]) -> _SourceBuild | None:
    """What to compile of a source FMU (FMI 2.0 or 3.0, Model Exchange or Co-Simulation), else None."""
    from fmpy import read_model_description

    try:
        description = read_model_description(str(path), validate=False)
    except Exception:  # an FMU fmpy cannot read: read_fmu refuses it with its own message
        return None
    interfaces = [i for i in (description.modelExchange, description.coSimulation) if i is not None]
    if description.fmiVersion not in ("2.0", "3.0") or not interfaces:
        return None
    every_c = sorted(n[len("sources/") :] for n in names if n.startswith("sources/") and n.endswith(".c"))
    libraries = {}
    for identifier in dict.fromkeys(i.modelIdentifier for i in interfaces):
        sets = [
            file_set
            for configuration in description.buildConfigurations or []
            if configuration.modelIdentifier == identifier
            for file_set in configuration.sourceFileSets
        ]
        listed = list(dict.fromkeys(name for file_set in sets for name in file_set.sourceFiles))
        flags = [
            f"-D{d.name}" + (f"={d.value}" if d.value is not None else "")
            for file_set in sets
            for d in file_set.preprocessorDefinitions
            if not d.optional
        ]
        flags += [f"-Isources/{folder}" for file_set in sets for folder in file_set.includeDirectories]
        libraries[identifier] = (listed or [n for n in every_c if "/" not in n], flags)
    return _SourceBuild(_platforms()[description.fmiVersion == "3.0"], libraries)


def source_build_key(path: Path) -> str:
    """SHA-256 of what a compiled source FMU depends on: the FMU, this module, fmpy and the compiler."""
    digest = hashlib.sha256(read_input_bytes(path, "FMU", MAX_ARCHIVE_BYTES))
    digest.update((resources.files("heliostep.fmu") / "sources.py").read_bytes())
    digest.update(f"fmpy {metadata.version('fmpy')}\0{compiler_version(compiler())}".encode())
    return digest.hexdigest()


def _has_binary(names: list[str], platform: str) -> bool:
    """Whether the archive holds a file (not only an empty folder) under ``binaries/<platform>/``."""
    return any(n.startswith(f"binaries/{platform}/") and not n.endswith("/") for n in names)


def with_platform_binary(path: Path, cache: Path) -> Path:
    """``path`` itself when it has a binary for this platform (or no sources); else its compiled copy
    in ``cache`` (compiled now unless a verified one is there)."""
    path = Path(path)
    try:
        with zipfile.ZipFile(path) as archive:
            names = archive.namelist()
            head = b""
            if "modelDescription.xml" in names:
                with archive.open("modelDescription.xml") as description:
                    head = description.read(4096)
    except (OSError, zipfile.BadZipFile, zlib.error, EOFError):
        return path  # read_fmu names what is wrong with it
    version = re.search(rb'fmiVersion\s*=\s*"([^"]*)"', head)
    platform = _platforms()[version is not None and version.group(1).startswith(b"3.")]
    if _has_binary(names, platform) or not any(n.startswith("sources/") for n in names):
        return path  # a binary for this platform (the common case: decided without parsing the XML), or no sources
    build = _source_build(path, names)
    if build is None:
        return path
    cache = private_cache(Path(cache))
    key = source_build_key(path)
    target = Path(cache) / SOURCE_CACHE / key[:16] / path.name
    if verified(target):
        return target
    try:
        with exclusive_lock(Path(cache) / ".build" / f"source-{key[:16]}.lock"):
            if not verified(target):
                _compile(path, names, build, target)
    except OSError as exc:
        raise InputError(
            f"{path}: a source FMU, to be compiled into the FMU cache {cache} ($HELIOSTEP_FMUS), which cannot be "
            f"written ({exc.strerror or exc}); point HELIOSTEP_FMUS at a writable folder"
        ) from None
    return target


def _compile(path: Path, names: list[str], build: _SourceBuild, target: Path) -> None:
    """Compile the FMU's sources into a copy with the binaries added, at ``target`` (digest beside it)."""
    work = Path(tempfile.mkdtemp(prefix=f"source-{path.stem}-{os.getpid()}-", dir=target.parents[2] / ".build"))
    try:
        with zipfile.ZipFile(path) as archive:
            archive.extractall(work / "fmu")
        libraries = {
            identifier: _compile_library(path, work, identifier, sources, flags)
            for identifier, (sources, flags) in build.libraries.items()
        }
        target.parent.mkdir(parents=True, exist_ok=True)
        partial = work / target.name
        with zipfile.ZipFile(path) as original, zipfile.ZipFile(partial, "w", zipfile.ZIP_DEFLATED) as copy:
            for name in names:
                copy.writestr(zipfile.ZipInfo(name, _FIXED_TIME), original.read(name), zipfile.ZIP_DEFLATED)
            for identifier, library in libraries.items():
                entry = zipfile.ZipInfo(f"binaries/{build.platform}/{identifier}.so", _FIXED_TIME)
                copy.writestr(entry, library.read_bytes(), zipfile.ZIP_DEFLATED)
        partial.replace(target)
        record = work / "digest"
        record.write_text(file_sha256(target) + "\n")
        record.replace(digest_path(target))  # the copy counts as compiled once this is in place
    finally:
        shutil.rmtree(work, ignore_errors=True)


def _compile_library(path: Path, work: Path, identifier: str, sources: list[str], flags: list[str]) -> Path:
    """``work/<identifier>.so`` compiled from the extracted FMU's ``sources`` (InputError naming the
    FMU and the compiler's first error when they do not compile)."""
    import fmpy

    folder = work / "fmu" / "sources"
    missing = [s for s in sources if not (folder / s).is_file()]
    if missing:
        raise InputError(f"{path}: its build description lists source files not in sources/: {', '.join(missing)}")
    library = work / f"{identifier}.so"
    headers = str(Path(fmpy.__file__).parent / "c-code")
    command = [compiler(), "-shared", "-fPIC", "-O2", "-I", "sources", "-I", headers, *flags]
    command += [f"sources/{s}" for s in sources] + ["-o", str(library), "-lm"]
    plain = {**os.environ, "LC_ALL": "C"}  # the compiler's messages in plain ASCII, paths inside the FMU
    result = subprocess.run(command, capture_output=True, text=True, cwd=work / "fmu", env=plain)
    if result.returncode != 0:
        raise InputError(f"{path}: a source FMU that does not compile: {_first_error(result.stderr + result.stdout)}")
    return library


def _first_error(output: str) -> str:
    """The compiler's first error line (else its first line)."""
    lines = [line.strip() for line in output.splitlines() if line.strip()]
    errors = [line for line in lines if "error" in line.lower()]
    return (errors or lines or ["the compiler failed and said nothing"])[0]
