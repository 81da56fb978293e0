"""An FMU's archive is checked before it is unpacked: its unpacked size against the disk budget,
entries whose declared size lies, names that leave the FMU's folder (each an InputError naming the file)."""

from __future__ import annotations

import struct
import zipfile

import pytest

from heliostep.cosim import read_fmu
from heliostep.errors import InputError
from third_party_fmu import build_mini_fmu


@pytest.fixture(scope="module")
def gain_fmu(tmp_path_factory):
    return build_mini_fmu("Gain", tmp_path_factory.mktemp("gain"))


def _with_entry(fmu, tmp_path, name: str, data: bytes):
    """A copy of ``fmu`` with one more entry (deflated)."""
    copy = tmp_path / fmu.name
    copy.write_bytes(fmu.read_bytes())
    with zipfile.ZipFile(copy, "a", zipfile.ZIP_DEFLATED) as archive:
        archive.writestr(name, data)
    return copy


def _declare_size(path, name: str, size: int) -> None:
    """Rewrite the uncompressed size ``name`` declares, in its local header and the central directory."""
    data = bytearray(path.read_bytes())
    encoded = name.encode()
    local = data.index(b"PK\x03\x04")
    while data[local + 30 : local + 30 + len(encoded)] != encoded:
        local = data.index(b"PK\x03\x04", local + 4)
    struct.pack_into("<I", data, local + 22, size)
    central = data.index(b"PK\x01\x02")
    while data[central + 46 : central + 46 + len(encoded)] != encoded:
        central = data.index(b"PK\x01\x02", central + 4)
    struct.pack_into("<I", data, central + 24, size)
    path.write_bytes(bytes(data))


def test_an_fmu_unpacking_beyond_the_disk_budget_is_refused_before_unpacking(gain_fmu, tmp_path):
    bomb = _with_entry(gain_fmu, tmp_path, "resources/zeros.bin", bytes(3_000_000))  # 3 MB, a few kB packed
    assert bomb.stat().st_size < 100_000
    with pytest.raises(InputError, match=r"Gain.fmu: unpacks to 0.003\d* GB, over the disk budget of 0.002 GB"):
        read_fmu(bomb, max_unpacked_bytes=2_000_000)
    assert read_fmu(bomb, max_unpacked_bytes=4_000_000).model_name == "Gain"


def test_an_entry_longer_than_it_declares_is_refused(gain_fmu, tmp_path):
    liar = _with_entry(gain_fmu, tmp_path, "resources/data.bin", bytes(100_000))
    _declare_size(liar, "resources/data.bin", 10)
    with pytest.raises(InputError, match=r"Gain.fmu: a damaged FMU archive \(BadZipFile: Bad CRC-32"):
        read_fmu(liar)


@pytest.mark.parametrize(
    "name, reason",
    [
        ("/tmp/escape.txt", "is absolute"),
        ("resources\\escape.txt", "has a backslash"),
        ("resources/../../escape.txt", r"climbs out of the FMU's folder"),
    ],
)
def test_an_entry_named_outside_the_fmu_folder_is_refused_naming_it(gain_fmu, tmp_path, name, reason):
    bad = tmp_path / "Gain.fmu"
    with zipfile.ZipFile(gain_fmu) as original, zipfile.ZipFile(bad, "w") as archive:
        for entry in original.infolist():
            archive.writestr(entry, original.read(entry))
        archive.writestr(zipfile.ZipInfo(name), b"x")
    with pytest.raises(InputError, match=rf"Gain.fmu: the entry .* {reason}"):
        read_fmu(bad)
