"""The mode of the files heliostep writes for the user: what the user's umask lets a new file have
(``0o666 & ~umask``, as ``open`` gives), also for a file written privately under a temporary name
(``0o600``, so nobody reads it half-written) and renamed into place (:func:`publish`)."""

from __future__ import annotations

import os
from pathlib import Path

__all__ = ["publish", "shared_mode", "umask"]


def umask() -> int:
    """The process's umask: read from ``/proc/self/status`` (Linux), else set and restored at once
    (``os.umask`` has no reader; a file another thread creates meanwhile gets the stricter ``0o077``)."""
    try:
        with open("/proc/self/status", encoding="ascii") as status:
            for line in status:
                if line.startswith("Umask:"):
                    return int(line.split()[1], 8)
    except (OSError, ValueError, IndexError):
        pass
    mask = os.umask(0o077)
    os.umask(mask)
    return mask


def shared_mode() -> int:
    """The mode a new file gets under the user's umask: ``0o666 & ~umask``."""
    return 0o666 & ~umask()


def publish(path: str | Path) -> None:
    """Give the file ``path`` (written privately, about to be renamed into place) :func:`shared_mode`;
    never through a symbolic link (one there: OSError)."""
    fd = os.open(path, os.O_RDONLY | getattr(os, "O_NOFOLLOW", 0))
    try:
        os.fchmod(fd, shared_mode())
    finally:
        os.close(fd)
