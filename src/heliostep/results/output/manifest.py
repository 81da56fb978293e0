"""The manifest of an output folder (``.heliostep-manifest.json``): each file heliostep wrote there, with its
size and sha256, so that a later command removes or replaces a file only while it is still the one written.

A file listed without a record (a manifest of an older heliostep, a file claimed while it is written in
place) or whose size or digest no longer match is not provably heliostep's: it is kept, and named.

Details: docs/running.md, ``heliostep.results.output.manifest``.
"""

from __future__ import annotations

import hashlib
import json
import os
import stat
from collections.abc import Mapping
from pathlib import Path

from heliostep.errors import InputError
from heliostep.results.output.files import TMP_PREFIX, refuse_link

__all__ = [
    "IN_PLACE",
    "MANIFEST_NAME",
    "FileRecord",
    "file_record",
    "is_in_place",
    "is_ours",
    "open_new",
    "read_records",
    "write_manifest",
]

MANIFEST_NAME = ".heliostep-manifest.json"

#: What the manifest holds of one file: {"size": bytes, "sha256": hex}; None: listed, not provably heliostep's.
FileRecord = dict | None

_CHUNK = 1 << 20


#: (device, inode, size, mtime, ctime) -> the record read from that file: a file is read once while it stays
#: as it was (a change, even with its mtime set back, moves its ctime).
_READ: dict[tuple[int, ...], dict] = {}


def file_record(path: Path) -> dict:
    """The size and sha256 of the plain file ``path`` (a symbolic link is not followed: InputError naming it)."""
    refuse_link(path)
    with open(path, "rb") as fh:
        info = os.fstat(fh.fileno())
        key = (info.st_dev, info.st_ino, info.st_size, info.st_mtime_ns, info.st_ctime_ns)
        if key not in _READ:
            digest, size = hashlib.sha256(), 0
            while chunk := fh.read(_CHUNK):
                digest.update(chunk)
                size += len(chunk)
            _READ[key] = {"size": size, "sha256": digest.hexdigest()}
    return dict(_READ[key])


#: The record of a file heliostep is updating in place (a sweep's table): no digest until the update ends.
IN_PLACE = {"in_place": True}


def is_in_place(path: Path, record: FileRecord) -> bool:
    """Whether ``record`` marks ``path`` as being updated in place and ``path`` is a plain file (not a link)."""
    try:
        return record == IN_PLACE and stat.S_ISREG(os.lstat(path).st_mode)
    except OSError:
        return False


def is_ours(path: Path, record: FileRecord) -> bool:
    """Whether ``path`` is a plain file (not a link) of the size and sha256 ``record`` gives."""
    if not isinstance(record, dict) or not isinstance(record.get("sha256"), str):
        return False
    try:
        info = os.lstat(path)
    except OSError:
        return False
    if not stat.S_ISREG(info.st_mode) or info.st_size != record.get("size"):
        return False
    return file_record(path)["sha256"] == record["sha256"]


def read_records(folder: str | Path) -> dict[str, FileRecord]:
    """The files the manifest in ``folder`` lists, name -> record (none without a manifest). Only plain names
    in the folder are taken (never a path out of it); a manifest that is a symbolic link is refused."""
    path = Path(folder) / MANIFEST_NAME
    refuse_link(path)
    try:
        record = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        return {}
    except (OSError, ValueError) as exc:
        raise InputError(
            f"{path}: heliostep's manifest cannot be read ({exc}); remove it to reuse the folder"
        ) from None
    files = record.get("files", []) if isinstance(record, dict) else []
    if isinstance(files, Mapping):
        return {n: (r if isinstance(r, dict) else None) for n, r in files.items() if _plain_name(n)}
    return {n: None for n in files if isinstance(n, str) and _plain_name(n)}  # an older manifest: names only


def _plain_name(name: object) -> bool:
    return isinstance(name, str) and bool(name) and name not in (".", "..") and not set("/\\\0") & set(name)


def write_manifest(folder: Path, records: Mapping[str, FileRecord], state: str) -> None:
    """``records`` as ``folder``'s manifest, written to a temporary file (never through a link) and renamed."""
    path = folder / MANIFEST_NAME
    refuse_link(path)
    tmp = folder / f"{TMP_PREFIX}{os.getpid()}-manifest.json"
    document = {"files": dict(sorted(records.items())), "state": state, "pid": os.getpid()}
    with open_new(tmp) as fh:
        fh.write(json.dumps(document, indent=1) + "\n")
        fh.flush()
        os.fsync(fh.fileno())
    os.replace(tmp, path)


def open_new(path: Path):
    """``path`` opened for writing text, never through a symbolic link (one there: InputError naming it)."""
    refuse_link(path)
    fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC | getattr(os, "O_NOFOLLOW", 0), 0o666)
    return os.fdopen(fd, "w", encoding="utf-8")
