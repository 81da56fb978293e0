"""An output folder's manifest records each file's size and sha256: only a file still as heliostep wrote it
is removed or replaced; one listed but changed, or listed by an older manifest without records, is kept and
named; a symbolic link where heliostep writes (the manifest, its temporary, a file swapped in) is refused.

Real folders and files, the functions the commands call.
"""

from __future__ import annotations

import hashlib
import json
import os
from pathlib import Path

import pytest

from heliostep.errors import InputError
from heliostep.results.output.files import TMP_PREFIX, check_out_dir
from heliostep.results.output.folder import (
    MANIFEST_NAME,
    check_foreign,
    claimed,
    hold_folder,
    swap_in,
    write_swapped,
)


def _write(names: dict[str, str]):
    def write(staging: Path) -> list[Path]:
        for name, text in names.items():
            (staging / name).write_text(text)
        return [staging / name for name in names]

    return write


def _manifest(folder: Path) -> dict:
    return json.loads((folder / MANIFEST_NAME).read_text())


def test_the_manifest_records_each_files_size_and_sha256(tmp_path):
    with hold_folder(tmp_path):
        write_swapped(tmp_path, _write({"a.csv": "1,2\n"}))
    assert _manifest(tmp_path)["files"]["a.csv"] == {"size": 4, "sha256": hashlib.sha256(b"1,2\n").hexdigest()}


def test_a_listed_file_changed_since_is_kept_and_named_not_removed(tmp_path, capsys):
    with hold_folder(tmp_path):
        write_swapped(tmp_path, _write({"a.csv": "ours\n", "b.csv": "ours\n"}))
        (tmp_path / "b.csv").write_text("the user's edit\n")
        write_swapped(tmp_path, _write({"c.csv": "new\n"}))
    assert (tmp_path / "b.csv").read_text() == "the user's edit\n"
    assert not (tmp_path / "a.csv").exists()  # ours, unchanged: removed
    err = capsys.readouterr().err
    assert "kept b.csv" in err and MANIFEST_NAME in err
    assert set(_manifest(tmp_path)["files"]) == {"c.csv"}  # b.csv no longer claimed


def test_a_manifest_copied_from_elsewhere_deletes_nothing(tmp_path, capsys):
    """A manifest listing ``notes.txt`` with another file's size and digest (copied, stale): notes.txt stays."""
    (tmp_path / "notes.txt").write_text("the user's notes\n")
    record = {"size": 3, "sha256": "0" * 64}
    (tmp_path / MANIFEST_NAME).write_text(json.dumps({"files": {"notes.txt": record}, "state": "complete"}))
    with hold_folder(tmp_path):
        write_swapped(tmp_path, _write({"a.csv": "ours\n"}))
    assert (tmp_path / "notes.txt").read_text() == "the user's notes\n"
    assert "kept notes.txt" in capsys.readouterr().err


def test_an_old_manifest_without_records_proves_nothing_ours(tmp_path, capsys):
    (tmp_path / "notes.txt").write_text("the user's notes\n")
    (tmp_path / MANIFEST_NAME).write_text(json.dumps({"files": ["notes.txt"], "state": "complete"}))
    with hold_folder(tmp_path):
        write_swapped(tmp_path, _write({"a.csv": "ours\n"}))
    assert (tmp_path / "notes.txt").read_text() == "the user's notes\n"
    assert "kept notes.txt" in capsys.readouterr().err


def test_a_listed_file_changed_since_is_refused_as_foreign_when_written_again(tmp_path):
    with hold_folder(tmp_path):
        write_swapped(tmp_path, _write({"a.csv": "ours\n"}))
        (tmp_path / "a.csv").write_text("the user's edit\n")
        with pytest.raises(InputError, match=r"a\.csv is listed in \.heliostep-manifest\.json but not as heliostep"):
            write_swapped(tmp_path, _write({"a.csv": "new\n"}))
    assert (tmp_path / "a.csv").read_text() == "the user's edit\n"


@pytest.mark.parametrize("kind", ["manifest", "manifest's temporary", "swapped-in file"])
def test_a_symbolic_link_where_heliostep_writes_is_refused_and_its_target_untouched(kind, tmp_path):
    target = tmp_path / "important.txt"
    target.write_text("a user's own words\n")
    folder = tmp_path / "out"
    folder.mkdir()
    with hold_folder(folder):
        write_swapped(folder, _write({"a.csv": "ours\n"}))
        name = {
            "manifest": MANIFEST_NAME,
            "manifest's temporary": f"{TMP_PREFIX}{os.getpid()}-manifest.json",
            "swapped-in file": "a.csv",
        }[kind]
        (folder / name).unlink(missing_ok=True)
        (folder / name).symlink_to(target)
        with pytest.raises(InputError, match="symbolic link|not as heliostep wrote it") as raised:
            write_swapped(folder, _write({"a.csv": "new\n"}))
    assert name in str(raised.value)
    assert target.read_text() == "a user's own words\n"
    assert (folder / name).is_symlink()


def test_a_symbolic_link_at_the_probe_is_refused_and_its_target_untouched(tmp_path):
    target = tmp_path / "important.txt"
    target.write_text("a user's own words\n")
    folder = tmp_path / "out"
    folder.mkdir()
    (folder / f"{TMP_PREFIX}probe-{os.getpid()}").symlink_to(target)
    with pytest.raises(InputError, match="symbolic link"):
        check_out_dir(folder)
    assert target.read_text() == "a user's own words\n"


def test_a_file_updated_in_place_is_recorded_when_its_block_ends_and_replaced_on_a_rerun(tmp_path):
    with hold_folder(tmp_path):
        with claimed(tmp_path, ["results.parquet"]):
            assert _manifest(tmp_path)["files"]["results.parquet"] == {"in_place": True}  # listed, being written
            (tmp_path / "results.parquet").write_text("rows\n")
            check_foreign(tmp_path, ["results.parquet"], in_place=["results.parquet"])  # its own command's again
            with pytest.raises(InputError, match="results.parquet is listed"):  # any other's: not provably ours
                check_foreign(tmp_path, ["results.parquet"])
        assert _manifest(tmp_path)["files"]["results.parquet"]["size"] == 5
        staging = tmp_path / f"{TMP_PREFIX}staging-x"
        staging.mkdir()
        (staging / "results.parquet").write_text("more rows\n")
        swap_in(tmp_path, staging, ["results.parquet"])  # ours: replaced, not refused
    assert (tmp_path / "results.parquet").read_text() == "more rows\n"
