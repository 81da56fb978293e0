"""A run owns its output folder: a lock for the run's life, a manifest of the files it wrote, and
its results swapped in at once.

No signal can leave an old run's files beside the new ones, and no run removes a file it did not write.

Details: docs/running.md, ``heliostep.results.output.folder``.
"""

from __future__ import annotations

import errno
import json
import os
import shutil
import signal
import socket
import sys
import tempfile
import threading
import time
from collections.abc import Callable, Iterable, Iterator
from contextlib import contextmanager
from pathlib import Path

from heliostep.errors import HeliostepError, InputError
from heliostep.results.output.files import TMP_PREFIX, check_out_dir, check_out_name, refuse_link
from heliostep.results.output.manifest import (
    IN_PLACE,
    MANIFEST_NAME,
    FileRecord,
    file_record,
    is_in_place,
    is_ours,
    read_records,
    write_manifest,
)

__all__ = [
    "LOCK_NAME",
    "MANIFEST_NAME",
    "FolderLock",
    "check_foreign",
    "claimed",
    "hold_folder",
    "manifest_files",
    "owned_folder",
    "remove_leftovers",
    "staging_folder",
    "swap_in",
    "write_swapped",
]

LOCK_NAME = ".heliostep-lock"
STAGING_PREFIX = TMP_PREFIX + "staging-"

#: Files written last into place and removed first: they say whether the run is complete.
RECORDS = ("metadata.json", "summary.json")

_HELD: dict[str, FolderLock] = {}  # folder (resolved) -> the lock this process holds on it


def _command_line() -> str:
    return " ".join([Path(sys.argv[0]).name, *sys.argv[1:]])[:300] if sys.argv else "python"


class FolderLock:
    """The lock of one output folder, held by this process (:func:`hold_folder`)."""

    def __init__(self, folder: Path, command: str | None = None):
        self.folder = Path(folder)
        self.path = self.folder / LOCK_NAME
        self.command = command or _command_line()
        self.fd: int | None = None
        self.took_over: dict | None = None  # the record of a dead holder whose lock was taken over

    def acquire(self) -> FolderLock:
        import fcntl

        while True:
            try:
                fd = os.open(self.path, os.O_RDWR | os.O_CREAT | getattr(os, "O_NOFOLLOW", 0), 0o644)
            except OSError as exc:
                if exc.errno == errno.ELOOP:  # a link where the lock goes: writing through it would touch its target
                    raise InputError(
                        f"--out {self.folder}: its lock {self.path} is a symbolic link, which heliostep did not "
                        "make and does not follow; remove it or choose another --out"
                    ) from None
                raise InputError(f"--out {self.folder}: cannot create its lock {self.path}: {exc.strerror}") from None
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except OSError as exc:
                holder = _read_record(fd)
                os.close(fd)
                if exc.errno not in (errno.EWOULDBLOCK, errno.EAGAIN, errno.EACCES):
                    raise InputError(f"--out {self.folder}: cannot lock {self.path}: {exc.strerror}") from None
                pid, command, since = (holder.get(k, "?") for k in ("pid", "command", "started"))
                raise InputError(
                    f"--out {self.folder}: the folder is in use by another heliostep run "
                    f"(pid {pid}: {command}, since {since}); wait for it to end or choose another --out"
                ) from None
            if not _same_file(fd, self.path):  # unlinked by its holder's release meanwhile: lock anew
                os.close(fd)
                continue
            previous = _read_record(fd)
            if previous:
                self.took_over = previous
            record = {"pid": os.getpid(), "command": self.command, "host": socket.gethostname()}
            record["started"] = time.strftime("%Y-%m-%dT%H:%M:%S%z")
            os.ftruncate(fd, 0)
            os.pwrite(fd, (json.dumps(record) + "\n").encode(), 0)
            self.fd = fd
            return self

    def release(self) -> None:
        if self.fd is None:
            return
        try:
            if _same_file(self.fd, self.path):
                self.path.unlink()
        except OSError:
            pass
        os.close(self.fd)
        self.fd = None


def _same_file(fd: int, path: Path) -> bool:
    try:
        return os.stat(path).st_ino == os.fstat(fd).st_ino
    except FileNotFoundError:
        return False


def _read_record(fd: int) -> dict:
    try:
        record = json.loads(os.pread(fd, 4096, 0).decode() or "{}")
    except (OSError, ValueError):
        return {}
    return record if isinstance(record, dict) else {}


@contextmanager
def hold_folder(folder: str | Path, command: str | None = None) -> Iterator[FolderLock]:
    """Hold ``folder``'s lock within the block (again within it: the same lock); on taking it,
    remove what dead runs left there (:func:`remove_leftovers`).

    A block left by a stop that asks for no more writing (a ``BaseException`` that is not an
    ``Exception``: a second Ctrl+C's ``ForcedStop``, ``KeyboardInterrupt``, ``SystemExit``) also
    removes every temporary file and folder (``.heliostep-tmp-*``) in ``folder`` before the lock
    goes: with the lock held since the dead runs' were removed, they are all this command's, and a
    stop can come between any two bytecodes, e.g. after a staging folder is made and before the
    ``try`` that removes it. A block left by an error keeps them (a streamed trace that nowhere else
    could take holds computed rows)."""
    folder = Path(folder)
    key = os.path.realpath(folder)
    if key in _HELD:
        yield _HELD[key]
        return
    lock = FolderLock(folder, command).acquire()
    _HELD[key] = lock
    try:
        remove_leftovers(folder)
        yield lock
    except BaseException as exc:
        if not isinstance(exc, Exception):
            _remove_all_temporaries(folder)
        raise
    finally:
        _HELD.pop(key, None)
        lock.release()


def _temporaries(folder: Path, spare: tuple[str, ...] = ()) -> list[Path]:
    """The temporary files and folders (``.heliostep-tmp-*``) in ``folder``, but those named ``spare*``."""
    return [
        entry
        for entry in Path(folder).iterdir()
        if entry.name.startswith(TMP_PREFIX) and not (spare and entry.name.startswith(spare))
    ]


def _remove_temporary(entry: Path) -> None:
    if entry.is_dir() and not entry.is_symlink():
        shutil.rmtree(entry, ignore_errors=True)
    else:
        entry.unlink(missing_ok=True)


def _remove_all_temporaries(folder: Path) -> None:
    """Every ``.heliostep-tmp-*`` file and folder in ``folder`` removed (errors ignored: the stop goes on)."""
    try:
        entries = _temporaries(folder)
    except OSError:
        return
    for entry in entries:
        try:
            _remove_temporary(entry)
        except OSError:
            pass


def remove_leftovers(folder: Path) -> list[Path]:
    """Remove the temporary files and folders (``.heliostep-tmp-*``) in ``folder`` not of this
    process: with the lock held, they are those of runs that died."""
    removed = _temporaries(folder, spare=(f"{TMP_PREFIX}{os.getpid()}-", f"{STAGING_PREFIX}{os.getpid()}-"))
    for entry in removed:
        _remove_temporary(entry)
    return removed


def manifest_files(folder: str | Path) -> set[str]:
    """The files the manifest in ``folder`` lists (none without one), whether or not they are still heliostep's."""
    return set(read_records(folder))


def _owned(folder: Path, in_place: Iterable[str] = ()) -> tuple[dict[str, FileRecord], list[str]]:
    """The manifest's records of the files in ``folder`` still as heliostep wrote them, and the names of
    those listed there that are not (changed, replaced, listed without a record: kept, never removed).
    ``in_place``: the files this command updates in place (a sweep's table): one a killed command left
    marked as being written (:func:`claimed`) is its own to take up again, proven by its content."""
    owned, changed, in_place = {}, [], set(in_place)
    for name, record in read_records(folder).items():
        if is_ours(folder / name, record) or (name in in_place and is_in_place(folder / name, record)):
            owned[name] = record
        elif os.path.lexists(folder / name):
            changed.append(name)
    return owned, sorted(changed)


def check_foreign(folder: str | Path, names: Iterable[str], in_place: Iterable[str] = ()) -> None:
    """Refuse (InputError) a folder holding a file named like one of ``names`` (those a run may
    write) that heliostep did not write there: not listed in its manifest, or no longer of the size and
    sha256 listed (``in_place``: see :func:`_owned`). heliostep replaces only its own files."""
    folder = Path(folder)
    _refuse_foreign(folder, names, *_owned(folder, in_place))


def _refuse_foreign(folder: Path, names: Iterable[str], owned: dict[str, FileRecord], changed: list[str]) -> None:
    """:func:`check_foreign` with the folder's own files and changed ones (:func:`_owned`) known."""
    foreign = sorted(n for n in set(names) if n not in owned and os.path.lexists(folder / n))
    if not foreign:
        return
    unlisted = [n for n in foreign if n not in changed]
    why = []
    if unlisted:
        why.append(f"{', '.join(unlisted)} {'is' if len(unlisted) == 1 else 'are'} not listed in {MANIFEST_NAME}")
    if len(unlisted) < len(foreign):
        others = [n for n in foreign if n in changed]
        why.append(
            f"{', '.join(others)} {'is' if len(others) == 1 else 'are'} listed in {MANIFEST_NAME} but not "
            "as heliostep wrote it (another size or sha256, or no record of them)"
        )
    one = len(foreign) == 1
    raise InputError(
        f"--out {folder}: {'; '.join(why)} (heliostep did not write {'it' if one else 'them'} and "
        f"replaces only its own files); move {'it' if one else 'them'} away or choose another --out"
    )


def _warn_kept(folder: Path, names: list[str]) -> None:
    """Say on stderr which listed files are kept: they are not (or no longer) the ones heliostep wrote."""
    if names:
        print(
            f"heliostep: warning: --out {folder}: kept {', '.join(names)}: listed in {MANIFEST_NAME} but not as "
            "heliostep wrote it (another size or sha256, or no record of it), so not heliostep's to remove",
            file=sys.stderr,
        )


def staging_folder(folder: str | Path) -> Path:
    """A new empty folder inside ``folder`` where a run's files are written before :func:`swap_in`."""
    return Path(tempfile.mkdtemp(prefix=f"{STAGING_PREFIX}{os.getpid()}-", dir=folder))


#: The signals a swap holds back (those that stop a command, :mod:`heliostep.cli.signals`).
HELD_SIGNALS = tuple(getattr(signal, name) for name in ("SIGINT", "SIGTERM", "SIGHUP") if hasattr(signal, name))


@contextmanager
def _stop_signals_blocked() -> Iterator[None]:
    """SIGINT, SIGTERM and SIGHUP held back within the block (delivered on leaving it).

    Masking them (``pthread_sigmask``) holds back only what is sent to this thread: a signal sent
    to the process (``kill``, Ctrl+C) then goes to a thread that does not mask it (OpenBLAS's,
    Arrow's, a helper thread), and Python runs its handler in the main thread at once, inside the
    block. So in the main thread the Python handlers are also replaced, within the block, by one
    that only notes the signal; on leaving, the handlers are put back and each signal noted is
    raised again, once (as the mask delivers a pending signal once). A signal ignored, or handled
    outside Python, keeps its disposition (and only the mask holds it back).
    """
    noted: list[int] = []

    def note(signum, frame):
        if signum not in noted:
            noted.append(signum)

    replaced = {}
    if threading.current_thread() is threading.main_thread():
        for sig in HELD_SIGNALS:
            current = signal.getsignal(sig)
            if callable(current) or current == signal.SIG_DFL:
                replaced[sig] = signal.signal(sig, note)
    masked = hasattr(signal, "pthread_sigmask")  # (not on Windows)
    previous = signal.pthread_sigmask(signal.SIG_BLOCK, HELD_SIGNALS) if masked else set()
    try:
        yield
    finally:
        if masked:
            signal.pthread_sigmask(signal.SIG_SETMASK, previous)  # a pending signal's handler: note()
        for sig, handler in replaced.items():
            signal.signal(sig, handler)  # (handles what is pending first: noted too)
        for signum in noted:
            signal.raise_signal(signum)  # to the handlers that were there before


def swap_in(folder: str | Path, staging: Path, names: Iterable[str], keep: Iterable[str] = ()) -> dict[str, Path]:
    """Replace the earlier run's files in ``folder`` (those its manifest lists and that are still as written,
    but those in ``keep``) by ``names`` from ``staging``: the old records removed first, the new ones renamed
    last, then the manifest of what is there now (each file's size and sha256); ``staging`` is removed. A
    listed file that is no longer as heliostep wrote it is kept and named on stderr. Returns name -> path."""
    folder, names, keep = Path(folder), list(dict.fromkeys(names)), set(keep)
    listed = read_records(folder)
    owned, changed = _owned(folder)
    _refuse_foreign(folder, names, owned, changed)
    kept = {n: listed[n] for n in keep if n in listed}
    old = {n: r for n, r in owned.items() if n not in keep}
    new = {name: file_record(staging / name) for name in names}
    for name in names:
        refuse_link(folder / name)
    _warn_kept(folder, [n for n in changed if n not in keep])
    order = sorted(names, key=lambda n: (n in RECORDS, RECORDS.index(n) if n in RECORDS else 0))
    with _stop_signals_blocked():
        write_manifest(folder, {**old, **kept, **new}, "swapping")  # a SIGKILL from here: all of them are ours
        for name in [n for n in RECORDS if n in old] + sorted(set(old) - set(RECORDS) - set(names)):
            (folder / name).unlink(missing_ok=True)  # the old records first: nothing claims the old run
        for name in order:
            os.replace(staging / name, folder / name)
        write_manifest(folder, {**kept, **new}, "complete")
    shutil.rmtree(staging, ignore_errors=True)
    return {name: folder / name for name in names}


@contextmanager
def claimed(folder: str | Path, names: Iterable[str]) -> Iterator[None]:
    """``names`` listed in ``folder``'s manifest while heliostep writes them in place within the block (a
    file a command updates as it goes, never swapped: a sweep's ``results.parquet``), then recorded with
    their size and sha256 however the block ends (a kill within it leaves them marked as being written: the
    same command takes them up again, :func:`owned_folder`'s ``in_place``, any other keeps them)."""
    folder, names = Path(folder), list(names)
    for name in names:
        refuse_link(folder / name)
    write_manifest(folder, {**read_records(folder), **{n: IN_PLACE for n in names}}, "complete")
    try:
        yield
    finally:
        records = read_records(folder)
        for name in names:
            present = os.path.isfile(folder / name) and not os.path.islink(folder / name)
            records[name] = file_record(folder / name) if present else None
        write_manifest(folder, records, "complete")


@contextmanager
def owned_folder(
    folder: str | Path, names: Iterable[str], command: str | None = None, in_place: Iterable[str] = ()
) -> Iterator[Path]:
    """``folder`` made if needed and proved writable, its lock held within the block
    (:func:`hold_folder`), and refused when it holds a file named like one of ``names`` (those the
    command may write) that its manifest does not list (:func:`check_foreign`). A folder this
    made is removed again when the block ends in a :class:`~heliostep.errors.HeliostepError`
    with the folder empty (bad input found while setting up). ``in_place``: the names the command updates
    in place (:func:`claimed`), its own again after a kill."""
    folder = check_out_name(str(folder))
    existed = folder.exists()
    check_out_dir(folder)
    try:
        with hold_folder(folder, command):
            check_foreign(folder, names, in_place)
            yield folder
    except HeliostepError:
        if not existed:
            try:
                folder.rmdir()
            except OSError:  # not empty: something was written
                pass
        raise


def write_swapped(
    folder: str | Path, write: Callable[[Path], Iterable[Path | None]], keep: Iterable[str] = ()
) -> dict[str, Path]:
    """The files ``write(staging)`` writes into a staging folder in ``folder`` (it returns their
    paths; None for one not written) swapped into ``folder`` (:func:`swap_in`: the earlier run's
    files but those in ``keep`` removed, signals held back meanwhile). Returns name -> path."""
    staging = staging_folder(folder)
    try:
        names = [Path(path).name for path in write(staging) if path is not None]
        return swap_in(folder, staging, names, keep)
    finally:
        shutil.rmtree(staging, ignore_errors=True)
