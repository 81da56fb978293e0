"""Build Types3, the FMI 3.0 Model Exchange pass-through of every variable type and an array
(``tests/data/mini3/types3.c`` with ``types3.xml``), with gcc against the FMI 3.0 headers fmpy ships.

No binary is committed: :func:`build_types3_fmu` compiles it into the folder given and packs it
with its ``modelDescription.xml`` and its sources.
"""

from __future__ import annotations

import subprocess
import tempfile
import zipfile
from pathlib import Path

from third_party_fmu3 import CFLAGS, MINI3_DIR, fmi3_headers

SOURCES = ("types3.c", "fmi3_stubs.c")  # the FMI 3.0 functions Types3 does not offer: stubs


def build_types3_fmu(out_dir: Path) -> Path:
    """Compile Types3 into ``out_dir/Types3.fmu``."""
    out_dir.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory() as work:
        library = Path(work) / "Types3.so"
        command = ["gcc", *CFLAGS, f"-I{fmi3_headers()}", "-o", str(library)]
        result = subprocess.run(
            command + [str(MINI3_DIR / s) for s in SOURCES] + ["-lm"], capture_output=True, text=True
        )
        if result.returncode != 0:
            raise RuntimeError(f"gcc failed for Types3:\n{result.stderr}")
        fmu = out_dir / "Types3.fmu"
        with zipfile.ZipFile(fmu, "w") as archive:
            archive.write(MINI3_DIR / "types3.xml", "modelDescription.xml")
            archive.write(library, "binaries/x86_64-linux/Types3.so")
            for source in SOURCES:
                archive.write(MINI3_DIR / source, f"sources/{source}")
    return fmu
