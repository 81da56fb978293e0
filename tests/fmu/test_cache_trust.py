"""The FMU cache is trusted only when it is the user's alone: created private (0700), and refused
(exit 2, naming the folder and the fix) when its group or others can write it or another user owns it,
as ssh refuses such key files. Real folders, the real command."""

from __future__ import annotations

import os
import stat
import subprocess
import sys

import pytest

from heliostep.errors import InputError
from heliostep.fmu.build import build_fmu
from heliostep.paths import fmus_dir, private_cache, scenarios_dir

CLI = "from heliostep.cli import console_main; console_main()"
CENTRAL = scenarios_dir() / "jan21-central.yaml"


def test_a_new_cache_is_created_private_to_the_user(tmp_path, monkeypatch):
    monkeypatch.setenv("HELIOSTEP_FMUS", str(tmp_path / "cache" / "fmus"))
    folder = fmus_dir()
    assert folder == tmp_path / "cache" / "fmus"
    assert stat.S_IMODE(folder.stat().st_mode) == 0o700


@pytest.mark.parametrize("mode", [0o777, 0o775, 0o757])
def test_a_cache_others_can_write_is_refused_naming_it_and_chmod(tmp_path, mode):
    cache = tmp_path / "fmus"
    cache.mkdir()
    cache.chmod(mode)
    completed = subprocess.run(
        [sys.executable, "-c", CLI, "run", str(CENTRAL), "--out", str(tmp_path / "out"), "--no-plots"],
        env={**os.environ, "HELIOSTEP_FMUS": str(cache)},
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert completed.returncode == 2 and "Traceback" not in completed.stderr, completed.stderr
    assert f"{cache}: the FMU cache is writable by others (mode {mode:03o})" in completed.stderr
    assert f"chmod go-w {cache}" in completed.stderr
    assert list(cache.iterdir()) == []  # nothing built into it
    with pytest.raises(InputError, match="the FMU cache is writable by others"):
        build_fmu("PanelMechanicsSmallAngle", cache)


@pytest.mark.skipif(os.geteuid() != 0, reason="giving a folder to another user takes root")
def test_a_cache_owned_by_another_user_is_refused(tmp_path):
    cache = tmp_path / "fmus"
    cache.mkdir(mode=0o700)
    os.chown(cache, 65534, 65534)  # nobody
    with pytest.raises(InputError, match=rf"{cache}: the FMU cache is owned by another user \(uid 65534\)"):
        private_cache(cache)


def test_a_cache_read_only_to_others_is_used(tmp_path):
    cache = tmp_path / "fmus"
    cache.mkdir(mode=0o755)
    cache.chmod(0o755)
    assert private_cache(cache) == cache
