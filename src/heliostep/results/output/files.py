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

__all__ = ["TMP_PREFIX", "atomic_path", "check_out_dir", "check_out_name", "write_text_atomic"]

TMP_PREFIX = ".heliostep-tmp-"
#: Longest name of one folder or file [bytes]: what Linux's file systems take (ext4, xfs, btrfs: NAME_MAX).
NAME_MAX = 255
#: Longest path the system calls take [bytes] (Linux's PATH_MAX, with room for the files written inside).
PATH_MAX = 4096 - 256


@contextmanager
def atomic_path(path: str | Path) -> Iterator[Path]:
    """Yield a temporary path beside ``path`` (same suffix); on success rename it to ``path``.

    On an exception the temporary file is removed and ``path`` is left as it was.
    """
    path = Path(path)
    tmp = path.with_name(f"{TMP_PREFIX}{uuid.uuid4().hex[:12]}-{path.name}")
    try:
        yield tmp
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


def check_out_name(text: str) -> Path:
    """``--out`` as given: an empty text (which ``Path`` would read as the current folder) and a name
    longer than the file system takes (:data:`NAME_MAX`, :data:`PATH_MAX`) are refused."""
    if not text.strip():
        raise InputError('--out: empty; name the output folder (e.g. "." for the current one)')
    path = Path(text)
    longest = max((len(os.fsencode(part)) for part in path.parts), default=0)
    if longest > NAME_MAX:
        raise InputError(f"--out {text[:60]}...: a name of {longest} bytes; expected at most {NAME_MAX} per folder")
    if len(os.fsencode(text)) > PATH_MAX:
        raise InputError(f"--out {text[:60]}...: a path of {len(os.fsencode(text))} bytes; expected at most {PATH_MAX}")
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
        with open(probe, "w") as fh:
            fh.write("probe")
        probe.unlink()
    except OSError as exc:
        raise InputError(f"--out {out_dir}: the output folder is not writable: {exc.strerror or exc}") from None
    return out_dir
