"""A full temporary folder (TMPDIR) is named as the place that is full, never ``--out``; nothing was computed, so
``--out`` is left as it was. The file systems are real: small tmpfs mounts (skipped where this user cannot mount)."""

from __future__ import annotations

import json
import os
import subprocess

import pytest

from heliostep_process import HELIOSTEP


@pytest.fixture
def small_tmpdir(tmp_path, request):
    """A tmpfs of ``request.param`` KiB mounted for the test, unmounted after it."""
    folder = tmp_path / "tmpdir"
    folder.mkdir()
    mounted = subprocess.run(
        ["mount", "-t", "tmpfs", "-o", f"size={request.param}k", "tmpfs", str(folder)], capture_output=True
    )
    if mounted.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here: {mounted.stderr.decode().strip()}")
    yield folder
    subprocess.run(["umount", str(folder)], check=True)


def _run(out, tmpdir) -> subprocess.CompletedProcess:
    return subprocess.run(
        [*HELIOSTEP, "run", "jan21-central", "--no-plots", "--out", str(out)],
        capture_output=True,
        text=True,
        timeout=300,
        env={**os.environ, "TMPDIR": str(tmpdir)},
    )


@pytest.mark.parametrize("small_tmpdir", [128], indirect=True)  # room for Python's probe, not for the FMUs
def test_a_full_tmpdir_is_named_and_out_is_left_alone(small_tmpdir, tmp_path, fmu_paths):
    out = tmp_path / "out"
    done = _run(out, small_tmpdir)
    assert done.returncode == 1, done.stderr
    assert "could not be unpacked into" in done.stderr and str(small_tmpdir) in done.stderr
    assert "TMPDIR" in done.stderr and "Traceback" not in done.stderr and str(out) not in done.stderr
    assert not out.exists()  # nothing computed: no folder made, nothing to rescue
    assert os.listdir(small_tmpdir) == []  # and nothing left in the full place


@pytest.mark.parametrize("small_tmpdir", [1024], indirect=True)  # room for the FMUs unpacked, little more
def test_a_tmpdir_with_room_for_the_fmus_alone_is_enough(small_tmpdir, tmp_path, fmu_paths):
    """The supervised child keeps its unsent rows in shared memory, not in a file: no TMPDIR space for them."""
    out = tmp_path / "out"
    done = _run(out, small_tmpdir)
    assert done.returncode == 0, done.stderr
    assert json.loads((out / "summary.json").read_text())["complete"] is True
    assert os.listdir(small_tmpdir) == []
