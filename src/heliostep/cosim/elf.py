"""What an ELF shared object is, read from its file without loading it: :func:`read_shared_object`.

An FMU's binary runs code when it is loaded (its constructors): loaded in heliostep's own process, a
constructor that crashes, exits or hangs would take the process down unnamed. So the process that checks
an FMU reads its binary as a file (its type, machine and exported functions) and leaves the loading to the
supervised child, which runs every call of FMU code.
"""

from __future__ import annotations

import struct
import sys
from pathlib import Path

__all__ = ["NotASharedObject", "read_shared_object"]

_ET_DYN = 3  # e_type of a shared object
_SHT_DYNSYM = 11
_STT_FUNC, _STB_GLOBAL, _STB_WEAK = 2, 1, 2


class NotASharedObject(ValueError):
    """The file is not an ELF shared object for this process's machine (the message says what it is)."""


def read_shared_object(path: Path) -> set[str]:
    """The functions the ELF shared object ``path`` exports (defined, global or weak, default visibility).

    Raises :class:`NotASharedObject` when it is no ELF file, not a shared object, or for another machine
    or word size than this interpreter's.
    """
    data = Path(path).read_bytes()
    header = _header(data)
    own = _header(Path(sys.executable).resolve().read_bytes()[:64]) if sys.executable else None
    bits, endian, kind, machine = header[:4]
    if kind != _ET_DYN:
        raise NotASharedObject(f"an ELF file of type {kind}, not a shared object")
    if own is not None and (bits, endian, machine) != own[:2] + own[3:4]:
        raise NotASharedObject(f"an ELF shared object for machine {machine} ({bits}-bit), not this one's {own[3]}")
    return _exported_functions(data, header)


def _header(data: bytes) -> tuple[int, str, int, int, int, int, int]:
    """(bits, byte order, type, machine, section headers' offset, their size, their count)."""
    if data[:4] != b"\x7fELF" or data[4] not in (1, 2) or data[5] not in (1, 2):
        raise NotASharedObject("not an ELF file")
    bits, endian = 32 * data[4], "<" if data[5] == 1 else ">"
    kind, machine = struct.unpack_from(endian + "HH", data, 16)
    if bits == 64:
        shoff, shentsize, shnum = (
            *struct.unpack_from(endian + "Q", data, 40),
            *struct.unpack_from(endian + "HH", data, 58),
        )
    else:
        shoff, shentsize, shnum = (
            *struct.unpack_from(endian + "I", data, 32),
            *struct.unpack_from(endian + "HH", data, 46),
        )
    return bits, endian, kind, machine, shoff, shentsize, shnum


def _sections(data: bytes, header: tuple) -> list[tuple[int, int, int, int, int]]:
    """Each section's (type, offset, size, linked section, entry size)."""
    bits, endian, _, _, shoff, shentsize, shnum = header
    layout = endian + ("IIQQQQIIQQ" if bits == 64 else "IIIIIIIIII")
    sections = []
    for k in range(shnum):
        _, kind, _, _, offset, size, link, _, _, entsize = struct.unpack_from(layout, data, shoff + k * shentsize)
        sections.append((kind, offset, size, link, entsize))
    return sections


def _exported_functions(data: bytes, header: tuple) -> set[str]:
    bits, endian = header[0], header[1]
    sections = _sections(data, header)
    names: set[str] = set()
    for kind, offset, size, link, entsize in sections:
        if kind != _SHT_DYNSYM or not entsize:
            continue
        strings = sections[link][1]
        for start in range(offset, offset + size, entsize):
            if bits == 64:
                name, info, other, shndx = struct.unpack_from(endian + "IBBH", data, start)
            else:
                name, _, _, info, other, shndx = struct.unpack_from(endian + "IIIBBH", data, start)
            binding, type_ = info >> 4, info & 0xF
            if shndx and type_ == _STT_FUNC and binding in (_STB_GLOBAL, _STB_WEAK) and other & 3 == 0:
                end = data.index(b"\0", strings + name)
                names.add(data[strings + name : end].decode(errors="replace"))
    return names
