"""Build the hand-written third-party-style test FMU ``BouncingBall`` (FMI 2.0 Model Exchange).

The FMU lives as source in ``tests/data/bouncing_ball/`` (``bouncing_ball.c`` and
``modelDescription.xml``); :func:`build_bouncing_ball` compiles it with gcc against
the FMI 2.0 headers that fmpy ships and packs the FMU, so no binary is committed.

Variables (value reference: name, causality):
    0 time (independent), 1 h (local state), 2 der(h), 3 v (local state, start 0),
    4 der(v), 5 g, 6 e, 7 h0, 8 t_kick (parameters), 9 f (input),
    10 height (output), 11 bounce_count (output, discrete).
Events: a state event at each impact (event indicator z = h), a time event at t_kick.
"""

from __future__ import annotations

import shutil
import subprocess
import tempfile
import zipfile
from pathlib import Path

SOURCE_DIR = Path(__file__).parent / "data" / "bouncing_ball"
MODEL_IDENTIFIER = "BouncingBall"
CFLAGS = ["-std=c99", "-O2", "-fPIC", "-shared", "-fvisibility=hidden",
          "-Wall", "-Wextra", "-Werror"]

#: value references, as in modelDescription.xml
VR = {"time": 0, "h": 1, "der(h)": 2, "v": 3, "der(v)": 4, "g": 5, "e": 6, "h0": 7,
      "t_kick": 8, "f": 9, "height": 10, "bounce_count": 11}


def fmi2_headers() -> Path:
    """The folder of the FMI 2.0 C headers that fmpy ships."""
    import fmpy

    return Path(fmpy.__file__).parent / "c-code"


def build_bouncing_ball(out_dir: Path) -> Path:
    """Compile ``BouncingBall`` and pack it as ``out_dir/BouncingBall.fmu``; return that path.

    Raises :class:`RuntimeError` with gcc's output when the compilation fails.
    """
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    fmu_path = out_dir / f"{MODEL_IDENTIFIER}.fmu"
    with tempfile.TemporaryDirectory(dir=out_dir) as tmp:
        library = Path(tmp) / f"{MODEL_IDENTIFIER}.so"
        gcc = shutil.which("gcc") or "gcc"
        command = [gcc, *CFLAGS, "-I", str(fmi2_headers()),
                   str(SOURCE_DIR / "bouncing_ball.c"), "-o", str(library), "-lm"]
        completed = subprocess.run(command, capture_output=True, text=True)
        if completed.returncode != 0:
            raise RuntimeError(f"compiling {MODEL_IDENTIFIER} failed:\n{' '.join(command)}\n"
                               f"{completed.stdout}{completed.stderr}")
        partial = Path(tmp) / fmu_path.name
        with zipfile.ZipFile(partial, "w", zipfile.ZIP_DEFLATED) as fmu:
            fmu.write(SOURCE_DIR / "modelDescription.xml", "modelDescription.xml")
            fmu.write(library, f"binaries/linux64/{MODEL_IDENTIFIER}.so")
        partial.replace(fmu_path)  # atomic: a reader never sees a half-written FMU
    return fmu_path
