"""The files ``heliostep run`` and ``heliostep export-ssp`` write get the mode the user's umask gives a new
file (``0o666 & ~umask``), as any program's: ``0o644`` under umask 022, ``0o600`` under 077. Each file is
written privately under a temporary name and renamed into place; a real process per umask (set before
the command starts, as a shell's ``umask`` does)."""

from __future__ import annotations

import os
import stat
import subprocess
import sys

import pytest

from heliostep.file_modes import shared_mode, umask
from heliostep.paths import scenarios_dir

RUN_BOTH = (
    "import os, sys\n"
    "os.umask(int(sys.argv[1], 8))\n"
    "from heliostep.cli import main\n"
    "out, ssp, scenario = sys.argv[2:5]\n"
    "short = ['--set', 'window.duration=5']\n"
    "assert main(['run', scenario, '--out', out, '--no-plots', '--csv', *short]) == 0\n"
    "assert main(['export-ssp', scenario, '--out', ssp, *short]) == 0\n"
)


@pytest.mark.parametrize(("mask", "mode"), [(0o022, 0o644), (0o077, 0o600)])
def test_run_and_export_ssp_files_get_the_users_umask(tmp_path, fmu_paths, mask, mode):
    out, ssp = tmp_path / "run", tmp_path / "system.ssp"
    scenario = str(scenarios_dir() / "jan21-central.yaml")
    done = subprocess.run(
        [sys.executable, "-c", RUN_BOTH, oct(mask), str(out), str(ssp), scenario], capture_output=True, text=True
    )
    assert done.returncode == 0, done.stderr
    written = [ssp, *sorted(out.iterdir())]
    assert {"trace.parquet", "trace.csv", "summary.json", "metadata.json"} <= {p.name for p in written}
    modes = {p.name: stat.S_IMODE(p.stat().st_mode) for p in written}
    assert modes == dict.fromkeys(modes, mode), modes


def test_the_umask_is_read_without_changing_it():
    before = os.umask(0o027)
    try:
        assert umask() == 0o027 and shared_mode() == 0o640
        assert os.umask(0o027) == 0o027  # (still the one set)
    finally:
        os.umask(before)
