"""A full temporary folder (TMPDIR) is named as the place that is full, never ``--out``; nothing was computed, so
``--out`` is left as it was. The file systems are real: small tmpfs mounts (skipped where this user cannot mount)."""

from __future__ import annotations

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


@pytest.mark.parametrize(
    ("small_tmpdir", "named"),
    [
        (128, "could not be unpacked into"),  # room for Python's probe, not for the FMUs unpacked
        (4096, "the supervised child's files could not be made in"),  # the FMUs fit, the child's row journal not
    ],
    indirect=["small_tmpdir"],
)
def test_a_full_tmpdir_is_named_and_out_is_left_alone(small_tmpdir, named, tmp_path, fmu_paths):
    out = tmp_path / "out"
    done = subprocess.run(
        [*HELIOSTEP, "run", "jan21-central", "--no-plots", "--out", str(out)],
        capture_output=True,
        text=True,
        timeout=300,
        env={**os.environ, "TMPDIR": str(small_tmpdir)},
    )
    assert done.returncode == 1, done.stderr
    assert named in done.stderr and str(small_tmpdir) in done.stderr and "TMPDIR" in done.stderr
    assert "Traceback" not in done.stderr and str(out) not in done.stderr
    assert not out.exists()  # nothing computed: no folder made, nothing to rescue
    assert os.listdir(small_tmpdir) == []  # and nothing left in the full place
