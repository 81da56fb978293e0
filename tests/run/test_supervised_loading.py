"""An FMU binary whose library constructor crashes, exits or hangs: heliostep's own process never loads it
(the FMU is checked from its file), so the supervised child that does fails named, exit 1, the watchdog
working and no temporary folder left. Real processes and a C FMU built here (``Faulty`` with a constructor)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from third_party_fmu import MINI_DIR, MINI_FMUS, _compile_and_pack, _model_description

CLI = "from heliostep.cli import console_main; console_main()"
CONSTRUCTORS = {  # what the library's constructor does: (C statement, how the message says the process ended)
    "segfault": ("*nowhere = 1;", "was killed by SIGSEGV"),
    "exit7": ("exit(7);", "exited with status 7 without finishing"),
    "hang": ("for (;;) spins++;", "the FMU hangs: no FMI call begun for 3 s (the watchdog)"),
}


def _fmu_with_constructor(folder: Path, behaviour: str) -> Path:
    """The Faulty FMU (no fault of its own) whose library runs ``CONSTRUCTORS[behaviour]`` when loaded."""
    source = folder / "constructor.c"
    source.write_text(
        "#include <stdlib.h>\n"
        "volatile int *nowhere = NULL;\nvolatile unsigned long spins = 0;\n"
        "__attribute__((constructor)) static void misbehave(void) { " + CONSTRUCTORS[behaviour][0] + " }\n"
    )
    return _compile_and_pack(
        "Faulty", [MINI_DIR / MINI_FMUS["Faulty"][0], source], [MINI_DIR], _model_description("Faulty"), folder
    )


@pytest.mark.parametrize("behaviour", sorted(CONSTRUCTORS))
def test_a_binary_whose_constructor_crashes_exits_or_hangs_fails_the_supervised_run_named(
    behaviour, tmp_path, fmu_paths
):
    fmu = _fmu_with_constructor(tmp_path, behaviour)
    scenario = tmp_path / "scenario.yaml"
    scenario.write_text(
        "name: constructor\n"
        "site: {latitude: 40.0, longitude: 14.25, altitude: 0.0, timezone: Europe/Rome}\n"
        'window: {date: 2025-01-21, start: "10:00", duration: 10}\n'
        "plant: {orientation: NS, tube_height: 3.0}\nmirror: {distance: 0.0, axis: secondary}\n"
        f"fmus: {{motor: StepperMotor, mechanics: PanelMechanics, faulty: {fmu}}}\n"
        "sequencer: {mode: one-phase-on, current: 5.5, step_angle: 1.8}\n"
    )
    out, private = tmp_path / "out", tmp_path / "tmp"
    private.mkdir()
    command = [sys.executable, "-c", CLI, "run", str(scenario), "--out", str(out), "--no-plots", "--watchdog", "3"]
    result = subprocess.run(
        command, env={**os.environ, "TMPDIR": str(private)}, capture_output=True, text=True, timeout=120
    )
    assert result.returncode == 1, result.stderr[-3000:]
    assert "Traceback" not in result.stderr
    ended = CONSTRUCTORS[behaviour][1]
    summary = json.loads((out / "summary.json").read_text())
    assert summary["complete"] is False and ended in summary["error"]
    assert "in loading the binary of FMU instance 'faulty' (model Faulty)" in summary["error"]
    assert sorted(p.name for p in private.iterdir()) == []
