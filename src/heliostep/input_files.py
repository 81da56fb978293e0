"""Opening a file the user named: a regular file, read with a size bound, else an :class:`InputError`.

Every input heliostep reads by a user's name (scenario, sweep and tolerance YAML, weather files, FMUs,
SSP archives, the traces ``compare`` reads) goes through :func:`open_input` or :func:`check_input_file`.
A name that is a directory, a FIFO (which would block the open until a writer comes, deaf to Ctrl+C),
a device (``/dev/zero`` never ends) or a socket is refused; so is a file larger than its kind's bound
(named constants below, each with its reason), before anything is read into memory. The open does not
wait on a FIFO (``O_NONBLOCK``) and a file that grows past its bound while read is refused too.
"""

from __future__ import annotations

import os
import stat
from pathlib import Path
from typing import BinaryIO

from heliostep.errors import InputError

_MIB = 1 << 20

#: Largest YAML file (scenario, sweep, ranges, tolerance, catalogue, signal mapping): they hold a few
#: kilobytes; the parsed nodes take about 100 times the text's size in memory.
MAX_YAML_BYTES = 16 * _MIB
#: Largest weather file: a TMY3 or EPW year hourly is under 2 MB, one at one-minute steps about 100 MB.
MAX_WEATHER_BYTES = 256 * _MIB
#: Largest CSV trace: the text, its lines and pandas' parse hold about four copies in memory (2 GB);
#: a larger trace belongs in Parquet, which is read one row group at a time.
MAX_CSV_BYTES = 512 * _MIB
#: Largest archive or binary table (an FMU, an SSP, a Parquet trace, a Modelica result file): the
#: shipped FMUs are a few megabytes, and an archive is read by its index, not whole.
MAX_ARCHIVE_BYTES = 4096 * _MIB

_KINDS = (
    (stat.S_ISDIR, "a directory"),
    (stat.S_ISFIFO, "a named pipe (FIFO)"),
    (stat.S_ISCHR, "a character device"),
    (stat.S_ISBLK, "a block device"),
    (stat.S_ISSOCK, "a socket"),
)


def _size_text(size: int) -> str:
    return f"{size:,} bytes"


def _check_status(path, what: str, status: os.stat_result, max_bytes: int) -> None:
    """Refuse a file that is not regular or is larger than ``max_bytes``."""
    if not stat.S_ISREG(status.st_mode):
        kind = next((name for test, name in _KINDS if test(status.st_mode)), "not a regular file")
        raise InputError(f"{path}: the {what} file is {kind}; expected a regular file")
    if status.st_size > max_bytes:
        raise InputError(
            f"{path}: the {what} file has {_size_text(status.st_size)}; expected at most {_size_text(max_bytes)}"
        )


def _unreadable(path, what: str, exc: OSError) -> InputError:
    if isinstance(exc, FileNotFoundError):
        return InputError(f"{path}: {what} file not found")
    return InputError(f"{path}: cannot read the {what} file: {exc.strerror or exc}")


def check_input_file(path: str | Path, what: str, max_bytes: int) -> Path:
    """``path`` if it is a regular file of at most ``max_bytes`` (for readers that open it themselves)."""
    try:
        status = os.stat(path)
    except OSError as exc:
        raise _unreadable(path, what, exc) from None
    _check_status(path, what, status, max_bytes)
    return Path(path)


def open_input(path: str | Path, what: str, max_bytes: int) -> BinaryIO:
    """The regular file ``path`` opened for reading in binary, checked before a byte is read.

    Raises
    ------
    InputError
        Naming the file and ``what`` it is: missing, unreadable, not a regular file, or larger
        than ``max_bytes``.
    """
    try:
        descriptor = os.open(path, os.O_RDONLY | os.O_NONBLOCK | os.O_CLOEXEC)
    except OSError as exc:
        raise _unreadable(path, what, exc) from None
    try:
        _check_status(path, what, os.fstat(descriptor), max_bytes)
        os.set_blocking(descriptor, True)
    except BaseException:
        os.close(descriptor)
        raise
    return os.fdopen(descriptor, "rb")


def read_input_bytes(path: str | Path, what: str, max_bytes: int) -> bytes:
    """The bytes of the regular file ``path``, at most ``max_bytes`` of them (see :func:`open_input`)."""
    with open_input(path, what, max_bytes) as handle:
        try:
            data = handle.read(max_bytes + 1)
        except OSError as exc:
            raise _unreadable(path, what, exc) from None
    if len(data) > max_bytes:  # grown since it was opened, or a size the system does not report
        raise InputError(f"{path}: the {what} file has more than {_size_text(max_bytes)}; expected at most that")
    return data


def read_input_text(path: str | Path, what: str, max_bytes: int, encoding: str = "utf-8") -> str:
    """The text of the regular file ``path`` (see :func:`read_input_bytes`), decoded."""
    data = read_input_bytes(path, what, max_bytes)
    try:
        return data.decode(encoding)
    except UnicodeDecodeError as exc:
        raise InputError(f"{path}: cannot read the {what} file: not {encoding} text ({exc.reason})") from None
