"""Writing a run's output folder safely: every file written to a temporary name and renamed into
place (:func:`atomic_path`), so none is ever cut short under its final name; :func:`check_out_dir`
finds an unusable folder before anything is computed.
"""

from __future__ import annotations

import os
import uuid
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from heliostep.errors import InputError
from heliostep.file_modes import publish

__all__ = ["TMP_PREFIX", "atomic_path", "check_out_dir", "check_out_name", "refuse_link", "write_text_atomic"]

TMP_PREFIX = ".heliostep-tmp-"
#: Longest name of one folder or file [bytes]: what Linux's file systems take (ext4, xfs, btrfs: NAME_MAX).
NAME_MAX = 255
#: Longest path the system calls take [bytes] (Linux's PATH_MAX, with room for the files written inside).
PATH_MAX = 4096 - 256


@contextmanager
def atomic_path(path: str | Path) -> Iterator[Path]:
    """Yield a temporary file beside ``path`` (same suffix, made new and readable by its owner only);
    on success give it the user's umask's mode (:func:`~heliostep.file_modes.publish`) and rename it to ``path``.

    On an exception the temporary file is removed and ``path`` is left as it was.
    """
    path = Path(path)
    tmp = path.with_name(f"{TMP_PREFIX}{uuid.uuid4().hex[:12]}-{path.name}")
    try:
        os.close(os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_NOFOLLOW", 0), 0o600))
        yield tmp
        refuse_link(path)  # a link planted meanwhile is not replaced (it is not heliostep's)
        publish(tmp)
        os.replace(tmp, path)
    except BaseException:
        try:
            tmp.unlink()
        except FileNotFoundError:
            pass
        raise


def write_text_atomic(path: str | Path, text: str) -> Path:
    path = Path(path)
    with atomic_path(path) as tmp, open(tmp, "w", encoding="utf-8") as fh:
        fh.write(text)
        fh.flush()
        os.fsync(fh.fileno())
    return path


def refuse_link(path: str | Path) -> None:
    """Refuse (InputError naming it) a symbolic link at ``path``, where heliostep is about to write: it did
    not make it, and writing through it (or over it) would touch a file it did not write."""
    if os.path.islink(path):
        raise InputError(
            f"{path} is a symbolic link, which heliostep did not make and does not follow or replace; "
            "remove it or choose another --out"
        )


def check_out_name(text: str) -> Path:
    """``--out`` as a path, ``~`` expanded as a shell user expects (the one place the commands turn --out into
    a path): an empty text (which ``Path`` would read as the current folder) and a name longer than the file
    system takes (:data:`NAME_MAX`, :data:`PATH_MAX`) are refused."""
    if not text.strip():
        raise InputError('--out: empty; name the output folder (e.g. "." for the current one)')
    path = Path(text).expanduser()
    longest = max((len(os.fsencode(part)) for part in path.parts), default=0)
    if longest > NAME_MAX:
        raise InputError(f"--out {text[:60]}...: a name of {longest} bytes; expected at most {NAME_MAX} per folder")
    length = len(os.fsencode(str(path)))
    if length > PATH_MAX:
        raise InputError(f"--out {text[:60]}...: a path of {length} bytes; expected at most {PATH_MAX}")
    return path


def check_out_dir(out_dir: str | Path) -> Path:
    """Create ``out_dir`` if needed and prove it writable (a probe file), or raise InputError."""
    out_dir = check_out_name(str(out_dir))
    if out_dir.exists() and not out_dir.is_dir():
        raise InputError(f"--out {out_dir}: exists and is not a folder")
    for parent in out_dir.parents:
        if parent.exists():
            if not parent.is_dir():
                raise InputError(f"--out {out_dir}: {parent} is a file, not a folder")
            break
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InputError(f"--out {out_dir}: cannot create the output folder: {exc.strerror or exc}") from None
    probe = out_dir / f"{TMP_PREFIX}probe-{os.getpid()}"
    try:
        refuse_link(probe)
        fd = os.open(probe, os.O_WRONLY | os.O_CREAT | os.O_TRUNC | getattr(os, "O_NOFOLLOW", 0), 0o666)
        try:
            os.write(fd, b"probe")
        finally:
            os.close(fd)
        probe.unlink()
    except OSError as exc:
        raise InputError(f"--out {out_dir}: the output folder is not writable: {exc.strerror or exc}") from None
    return out_dir
