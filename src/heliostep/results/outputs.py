"""Writing a run's output folder safely.

* every file goes to a temporary name in the same folder first and is renamed into place
  (:func:`atomic_path`), so no file is ever cut short under its final name: a run killed while
  writing leaves the previous file (or none) and a ``.heliostep-tmp-*`` file at most;
* :func:`check_out_dir` finds an unusable output folder before anything is computed;
* :func:`remove_stale` removes files of heliostep's own kinds that an earlier run left in the
  folder and the new run did not write.
"""

from __future__ import annotations

import os
import re
import uuid
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from pathlib import Path

from heliostep.errors import InputError

__all__ = ["OWN_FILES", "TMP_PREFIX", "atomic_path", "check_out_dir", "remove_stale", "write_text_atomic"]

TMP_PREFIX = ".heliostep-tmp-"

#: The files ``heliostep run`` writes: a rerun owns (and may remove) these in its folder.
OWN_FILES = re.compile(r"^(trace\.(parquet|csv)|summary\.json|metadata\.json|fig\d\d_[A-Za-z0-9_]+\.png)$")


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


def check_out_dir(out_dir: str | Path) -> Path:
    """Create ``out_dir`` if needed and prove it writable (a probe file), or raise InputError."""
    out_dir = Path(out_dir)
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


def remove_stale(out_dir: str | Path, written: Iterable[str | Path]) -> list[Path]:
    """Remove heliostep's own files (:data:`OWN_FILES`) and temporary files in ``out_dir``
    that are not in ``written``; returns what was removed. Other files are left alone."""
    out_dir = Path(out_dir)
    keep = {Path(p).name for p in written}
    removed = []
    for entry in out_dir.iterdir():
        if entry.name in keep or not entry.is_file():
            continue
        if OWN_FILES.match(entry.name) or entry.name.startswith(TMP_PREFIX):
            try:
                entry.unlink()
                removed.append(entry)
            except OSError:
                pass
    return removed
