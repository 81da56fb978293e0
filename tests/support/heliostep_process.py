"""``heliostep`` in a subprocess, for the tests that signal, kill or race real commands."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

from heliostep.paths import scenarios_dir

#: The command line of ``heliostep`` as installed (its entry point, ``heliostep.cli.console_main``), run by this
#: interpreter (the venv's, whatever is on PATH).
HELIOSTEP = [sys.executable, "-c", "from heliostep.cli import console_main; console_main()"]


def popen_heliostep(
    args: list[str], tmp: Path | None = None, env: dict[str, str] | None = None, cwd: Path | None = None
) -> subprocess.Popen:
    """``heliostep ARGS`` started (in ``cwd``), its output piped (text); with ``tmp``, a TMPDIR of
    its own (made if missing) to see what it leaves there; ``env``: more environment variables."""
    environment = {**os.environ, **(env or {})}
    if tmp is not None:
        tmp.mkdir(exist_ok=True)
        environment["TMPDIR"] = str(tmp)
    return subprocess.Popen(
        [*HELIOSTEP, *args], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=environment, cwd=cwd
    )


def five_day_scenario(folder: Path) -> Path:
    """jan21-day over five days from sunrise (a simulation of tens of seconds, still running when
    a signal comes or a second command starts: one day alone takes about a second)."""
    text = (scenarios_dir() / "jan21-day.yaml").read_text().replace("name: jan21-day", "name: jan21-five-days")
    text = text.replace("end: sunset", "duration: 432000")
    assert "duration: 432000" in text
    path = folder / "jan21-five-days.yaml"
    path.write_text(text)
    return path
