"""``heliostep run``'s figures are drawn by its drawer (:func:`heliostep.run.drawing.start_drawer`: forked before
the simulation, the plotting modules imported meanwhile): the command's own process never imports matplotlib,
no process of it is left once the command returns, and the PNGs are those drawn without a drawer, byte for byte.

Real processes: the command on a 10-second window of the paper's case in a fresh interpreter that reports the
modules it ended with and its child processes still there when ``main`` returned.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from heliostep.paths import scenarios_dir
from heliostep.results.run_files import FIGURE_FILES, POWER_FILE

RUN_AND_REPORT = (
    "import json, os, sys\n"
    "from pathlib import Path\n"
    "from heliostep.cli import main\n"
    "status = main(sys.argv[1:])\n"
    "me = str(os.getpid())\n"
    "children = [p.name for p in Path('/proc').iterdir() if p.name.isdigit() and _ppid(p) == me]\n"
    "print(json.dumps({'status': status, 'modules': sorted(sys.modules), 'children': children}))\n"
)
PPID = (
    "def _ppid(proc):\n"
    "    try:\n"
    "        return (proc / 'stat').read_text().rsplit(')', 1)[1].split()[1]\n"
    "    except OSError:\n"
    "        return None\n"
)


def _run(out: Path, parallel: str, window: list[str]) -> dict:
    args = ["run", str(scenarios_dir() / "jan21-central.yaml"), "--out", str(out), "--no-csv", *window]
    env = {**os.environ, "HELIOSTEP_PARALLEL_PLOTS": parallel}
    done = subprocess.run([sys.executable, "-c", PPID + RUN_AND_REPORT, *args], capture_output=True, text=True, env=env)
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout.strip().splitlines()[-1])


#: A window whose trace is held in memory (drawn while the records are written), and one over an hour, whose
#: trace is streamed to its file (drawn from the file after the records are in place).
WINDOWS = {
    "held": ["--set", "window.duration=10"],
    "streamed": ["--set", "window.duration=3700", "--set", "output.interval=60", "--set", "output.step_detail=0"],
}


@pytest.mark.parametrize("window", sorted(WINDOWS))
def test_the_drawer_draws_the_figures_and_is_gone_when_the_command_returns(tmp_path, window):
    drawn = _run(tmp_path / "drawer", "1", WINDOWS[window])
    assert drawn["status"] == 0
    assert "matplotlib" not in drawn["modules"]  # the drawer drew them: this process never imported matplotlib
    assert drawn["children"] == []  # the drawer (and the child it forked) killed and reaped: none left
    alone = _run(tmp_path / "alone", "0", WINDOWS[window])  # no fork: drawn here, one after the other
    assert "matplotlib" in alone["modules"] and alone["children"] == []
    for name in [*FIGURE_FILES, POWER_FILE]:
        png = (tmp_path / "drawer" / name).read_bytes()
        assert png[:8] == b"\x89PNG\r\n\x1a\n" and png == (tmp_path / "alone" / name).read_bytes(), name
    assert not list((tmp_path / "drawer").glob(".heliostep-tmp-*"))  # the staging folder and the job's spool gone
