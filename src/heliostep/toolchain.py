"""What the project's compiled artefacts (FMUs, the co-simulation kernel) share: the compiler's
version line for their cache keys and an exclusive lock for building into a shared cache."""

from __future__ import annotations

import fcntl
import subprocess
from contextlib import contextmanager
from pathlib import Path


def compiler_version(compiler: str) -> str:
    """The first line of ``compiler --version`` ("cc ?" when it prints nothing); OSError if it cannot run."""
    output = subprocess.run([compiler, "--version"], capture_output=True, text=True, check=False).stdout
    return output.splitlines()[0] if output else "cc ?"


@contextmanager
def exclusive_lock(path: Path):
    """An exclusive lock on ``path`` (processes building the same artefact wait for each other)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "w") as handle:
        fcntl.flock(handle, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(handle, fcntl.LOCK_UN)
