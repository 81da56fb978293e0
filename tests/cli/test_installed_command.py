"""The installed ``heliostep`` command (:func:`heliostep.cli.console_main`) in a real process: its report, its
files whole and its exit status, on 10 s of the paper's case and on bad input."""

from __future__ import annotations

import json
import subprocess

import pyarrow.parquet as pq

from heliostep.paths import scenarios_dir
from heliostep_process import HELIOSTEP


def test_the_installed_command_exits_with_its_report_and_files_whole(tmp_path):
    command = [*HELIOSTEP, "run"]
    scenario = str(scenarios_dir() / "jan21-central.yaml")
    out = tmp_path / "run"
    done = subprocess.run(
        [*command, scenario, "--out", str(out), "--no-plots", "--set", "window.duration=10"],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert done.returncode == 0, done.stderr
    assert done.stdout.rstrip().splitlines()[-1].split()[:2] == ["wall", "time"]  # the report's last line
    summary = json.loads((out / "summary.json").read_text())
    assert summary["complete"] is True and summary["duration_s"] == 10
    assert pq.read_metadata(out / "trace.parquet").num_rows == summary["rows"] > 0  # the trace whole
    bad = subprocess.run(
        [*command, scenario, "--out", str(tmp_path / "bad"), "--set", "window.duration=-1"],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert bad.returncode == 2 and "window.duration" in bad.stderr


#: A process that, as the installed command does, holds the stop signals until it exits, then signals itself.
_SIGNALLED_AT_EXIT = """
import os, signal, sys
from heliostep.cli.signals import signals_until_exit
signals_until_exit()
for _ in range(int(sys.argv[1])):
    os.kill(os.getpid(), signal.SIGINT)
    print("went on", flush=True)
sys.exit(3)
"""


def test_a_stop_signal_after_the_command_returned_does_not_cut_its_exit_a_second_ends_it_at_once():
    """One SIGINT while the command exits: the exit goes on with the command's status (3 here); a second
    ends the process at once with 130, never with Python's KeyboardInterrupt (status -2)."""
    import sys

    once = subprocess.run([sys.executable, "-c", _SIGNALLED_AT_EXIT, "1"], capture_output=True, text=True, timeout=60)
    assert (once.returncode, once.stdout, once.stderr) == (3, "went on\n", "")
    twice = subprocess.run([sys.executable, "-c", _SIGNALLED_AT_EXIT, "2"], capture_output=True, text=True, timeout=60)
    assert (twice.returncode, twice.stdout, twice.stderr) == (130, "went on\n", "")
