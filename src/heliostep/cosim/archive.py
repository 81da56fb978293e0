"""An FMU's archive checked before anything is unpacked: its entries' names and its unpacked size.

A small archive can declare gigabytes (a zip bomb) and an entry can name a place outside the folder
it is unpacked to (``/etc/...``, ``..\\..``): :func:`check_fmu_archive` refuses both from the zip's
index alone, and :func:`unpack` writes each entry through a bound of its declared size, so an entry
whose data is longer than it declares is refused rather than written.
"""

from __future__ import annotations

import shutil
import zipfile
import zlib
from pathlib import Path, PurePosixPath

from heliostep.errors import InputError
from heliostep.input_files import MAX_ARCHIVE_BYTES, open_input

#: Unpacked size an FMU may have when no budget is given: the scenario's default ``budget.disk_gb``.
DEFAULT_MAX_UNPACKED_BYTES = 10 * 10**9

_CHUNK = 1 << 20


def _bad_name(name: str) -> str | None:
    """Why an entry's name cannot be unpacked inside a folder, or None."""
    if "\\" in name:
        return "has a backslash (an FMU's paths use forward slashes)"
    if name.startswith("/") or ":" in name:
        return "is absolute (a leading slash or a drive letter)"
    if ".." in PurePosixPath(name).parts:
        return "climbs out of the FMU's folder (..)"
    return None


def _entries(path: Path) -> list[zipfile.ZipInfo]:
    """The zip's index of the FMU ``path`` (a regular file of at most ``MAX_ARCHIVE_BYTES``)."""
    with open_input(path, "FMU", MAX_ARCHIVE_BYTES) as handle:
        try:
            with zipfile.ZipFile(handle) as archive:
                return archive.infolist()
        except (zipfile.BadZipFile, zlib.error, EOFError, ValueError) as exc:
            raise InputError(f"{path}: not a readable FMU ({exc})") from None


def check_fmu_archive(path: str | Path, max_unpacked_bytes: int = DEFAULT_MAX_UNPACKED_BYTES) -> None:
    """Refuse an FMU whose entries have names that leave its folder or that unpacks to more than
    ``max_unpacked_bytes`` (the sum of its entries' declared sizes), naming the file."""
    path = Path(path)
    entries = _entries(path)
    for entry in entries:
        reason = _bad_name(entry.filename)
        if reason is not None:
            raise InputError(f"{path}: the entry {entry.filename!r} {reason}; expected a relative path")
    total = sum(entry.file_size for entry in entries)
    if total > max_unpacked_bytes:
        raise InputError(
            f"{path}: unpacks to {total / 1e9:.3g} GB, over the disk budget of {max_unpacked_bytes / 1e9:.3g} GB "
            "(budget.disk_gb); expected an FMU that fits it"
        )


def _copy_bounded(source, target, declared: int) -> int:
    """Copy ``source`` to ``target``, stopping one byte past ``declared``; the bytes copied."""
    copied = 0
    while copied <= declared:
        block = source.read(min(_CHUNK, declared + 1 - copied))
        if not block:
            break
        target.write(block)
        copied += len(block)
    return copied


def unpack(path: Path, folder: Path) -> None:
    """Unpack the FMU ``path`` (checked by :func:`check_fmu_archive`) into ``folder``, each entry no
    longer than it declares."""
    with open_input(path, "FMU", MAX_ARCHIVE_BYTES) as handle, zipfile.ZipFile(handle) as archive:
        for entry in archive.infolist():
            if _bad_name(entry.filename) is not None:
                raise InputError(f"{path}: the entry {entry.filename!r} is not a relative path inside the FMU")
            target = folder / entry.filename
            if entry.is_dir():
                target.mkdir(parents=True, exist_ok=True)
                continue
            target.parent.mkdir(parents=True, exist_ok=True)
            with archive.open(entry) as source, open(target, "wb") as out:
                copied = _copy_bounded(source, out, entry.file_size)
            if copied != entry.file_size:
                raise InputError(
                    f"{path}: the entry {entry.filename!r} declares {entry.file_size} bytes but unpacks to "
                    f"{'more' if copied > entry.file_size else copied}; expected its declared size"
                )


def remove_unpacked(folder: Path) -> None:
    """Remove a folder :func:`unpack` wrote (also when it failed half-way)."""
    shutil.rmtree(folder, ignore_errors=True)
