"""The master's own C libraries (the kernel, the FMI 3.0 adapter): compiled at first use, cached by content."""

from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
import tempfile
from collections.abc import Sequence
from pathlib import Path

from heliostep.errors import RunFailure
from heliostep.paths import fmus_dir, private_cache
from heliostep.progress import note
from heliostep.toolchain import compiler_version, exclusive_lock

__all__ = ["KernelBuildError", "compiled_library", "kernels_dir"]


class KernelBuildError(RunFailure):
    """The C compiler could not build one of the master's libraries (a run failure)."""


def kernels_dir() -> Path:
    """The cache of compiled libraries: beside the FMU cache, private to the user as it is."""
    return private_cache(fmus_dir().parent / "kernels")


def _compiler() -> str:
    return os.environ.get("CC") or shutil.which("cc") or shutil.which("gcc") or "cc"


def compiled_library(stem: str, what: str, sources: Sequence[Path], flags: Sequence[str] = ()) -> Path:
    """The shared library ``stem_<digest>.so`` of ``sources`` (the C files compiled, the others included
    by them), built once with ``flags`` into :func:`kernels_dir` under a name derived from the SHA-256 of
    the sources and the compiler's version; ``what`` names it in a build error."""
    cc = _compiler()
    try:
        version = compiler_version(cc)
    except OSError as exc:
        raise KernelBuildError(f"no C compiler for {what} ({cc}): {exc}") from None
    texts = [source.read_bytes() for source in sources]
    digest = hashlib.sha256(b"\0".join([*texts, version.encode()])).hexdigest()[:24]
    folder = kernels_dir()
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / f"{stem}_{digest}.so"
    if path.exists():
        return path
    with exclusive_lock(folder / ".lock"):
        if path.exists():
            return path
        note(f"heliostep: compiling {what} (first use, cached in {folder})")
        with tempfile.TemporaryDirectory(dir=folder) as work:
            copies = [Path(work) / source.name for source in sources]
            for copy, text in zip(copies, texts):  # compiled as hashed
                copy.write_bytes(text)
            target = Path(work) / path.name
            compiled = [str(copy) for copy in copies if copy.suffix == ".c"]
            result = subprocess.run(
                [cc, *flags, "-O2", "-Wall", "-Wextra", "-Werror", "-shared", "-fPIC", "-o", str(target), *compiled]
                + ["-lm"],
                capture_output=True,
                text=True,
            )
            if result.returncode != 0:
                raise KernelBuildError(f"compiling {what} failed:\n{result.stderr}")
            os.replace(target, path)  # atomic: other processes see no half-written library
    return path
