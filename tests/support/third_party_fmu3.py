"""Build the mini FMI 3.0 Model Exchange test FMUs of ``tests/data/mini3/`` (C, ``mini3_fmu.h``).

:func:`build_mini3_fmu` compiles one with gcc against the FMI 3.0 headers fmpy ships and packs it
with a ``modelDescription.xml`` written from :data:`MINI3_FMUS` (binaries in FMI 3.0's platform
tuple folder, ``binaries/x86_64-linux``); ``extra`` adds declarations heliostep must refuse (a
clock, an array variable) and ``interface`` swaps Model Exchange for Co-Simulation. No binary is
committed.

Counter3 -- count (Int32 output) +1 at each time event k * period, odd (Boolean output) its
parity, x (Float64 output, state) with der(x) = scale (Float32 parameter); terminates at the
first event at or after t_stop. Threshold3 -- tau dy/dt = u - y, a state event where y crosses
level: above (Boolean output), crossings (Int32 output).
"""

from __future__ import annotations

import shutil
import subprocess
import tempfile
import zipfile
from pathlib import Path

MINI3_DIR = Path(__file__).parents[1] / "data" / "mini3"
#: every FMI 3.0 function some test FMU does not define, each a weak symbol returning fmi3Error (its own wins)
FMI3_STUBS = MINI3_DIR / "fmi3_stubs.c"
CFLAGS = ["-std=c99", "-O2", "-fPIC", "-shared", "-Wall", "-Wextra", "-Werror", "-Wno-unused-parameter"]

#: name -> (source, token, variables (type, name, causality, variability, start or None, derivative-of vr),
#: event indicator value references); each variable's value reference is its index
MINI3_FMUS = {
    "Counter3": (
        "counter3.c",
        "{c0a7e1f2-3001-4000-8000-000000000001}",
        [
            ("Float64", "time", "independent", "continuous", None, None),
            ("Int32", "count", "output", "discrete", None, None),
            ("Boolean", "odd", "output", "discrete", None, None),
            ("Float64", "x", "output", "continuous", "0", None),
            ("Float64", "der(x)", "local", "continuous", None, 3),
            ("Float64", "period", "parameter", "fixed", "1", None),
            ("Float64", "t_stop", "parameter", "fixed", "4.5", None),
            ("Float32", "scale", "parameter", "fixed", "1", None),
        ],
        [],
    ),
    "Threshold3": (
        "threshold3.c",
        "{c0a7e1f2-3002-4000-8000-000000000002}",
        [
            ("Float64", "time", "independent", "continuous", None, None),
            ("Float64", "u", "input", "continuous", "1", None),
            ("Float64", "y", "output", "continuous", "0", None),
            ("Float64", "der(y)", "local", "continuous", None, 2),
            ("Boolean", "above", "output", "discrete", None, None),
            ("Int32", "crossings", "output", "discrete", None, None),
            ("Float64", "tau", "parameter", "fixed", "0.5", None),
            ("Float64", "level", "parameter", "fixed", "0.5", None),
            ("Float64", "y0", "parameter", "fixed", "0", None),
            ("Float64", "z", "local", "continuous", None, None),
        ],
        [9],
    ),
}


def _model_description(name: str, extra: str = "", interface: str = "ModelExchange") -> str:
    _, token, variables, indicators = MINI3_FMUS[name]
    lines = []
    for vr, (type_, var, causality, variability, start, derivative) in enumerate(variables):
        attributes = f'name="{var}" valueReference="{vr}" causality="{causality}" variability="{variability}"'
        if start is not None:
            attributes += f' start="{start}"'
            if causality == "output":
                attributes += ' initial="exact"'
        if derivative is not None:
            attributes += f' derivative="{derivative}"'
        lines.append(f"    <{type_} {attributes}/>")
    outputs = [vr for vr, v in enumerate(variables) if v[2] == "output"]
    derivatives = [vr for vr, v in enumerate(variables) if v[5] is not None]
    structure = [f'    <Output valueReference="{vr}"/>' for vr in outputs]
    structure += [f'    <ContinuousStateDerivative valueReference="{vr}"/>' for vr in derivatives]
    structure += [f'    <EventIndicator valueReference="{vr}"/>' for vr in indicators]
    return "\n".join(
        [
            '<?xml version="1.0" encoding="UTF-8"?>',
            f'<fmiModelDescription fmiVersion="3.0" modelName="{name}" instantiationToken="{token}">',
            f'  <{interface} modelIdentifier="{name}"/>',
            "  <ModelVariables>",
            *lines,
            extra,
            "  </ModelVariables>",
            "  <ModelStructure>",
            *structure,
            "  </ModelStructure>",
            "</fmiModelDescription>",
            "",
        ]
    )


def fmi3_headers() -> Path:
    """The folder of the FMI 3.0 C headers that fmpy ships."""
    import fmpy

    return Path(fmpy.__file__).parent / "c-code"


def build_mini3_fmu(name: str, out_dir: Path, extra: str = "", interface: str = "ModelExchange") -> Path:
    """Compile the mini FMI 3.0 FMU ``name`` into ``out_dir/<name>.fmu`` (with ``extra``
    variable declarations and the ``interface`` element given)."""
    source, _, _, _ = MINI3_FMUS[name]
    out_dir.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory() as work:
        library = Path(work) / f"{name}.so"
        result = subprocess.run(
            [
                "gcc",
                *CFLAGS,
                f"-I{fmi3_headers()}",
                f"-I{MINI3_DIR}",
                "-o",
                str(library),
                str(MINI3_DIR / source),
                str(FMI3_STUBS),
            ]
            + ["-lm"],
            capture_output=True,
            text=True,
        )
        if result.returncode != 0:
            raise RuntimeError(f"gcc failed for {name}:\n{result.stderr}")
        fmu = out_dir / f"{name}.fmu"
        with zipfile.ZipFile(fmu, "w") as archive:
            archive.writestr("modelDescription.xml", _model_description(name, extra, interface))
            archive.write(library, f"binaries/x86_64-linux/{name}.so")
            archive.writestr(f"sources/{source}", (MINI3_DIR / source).read_text())
    shutil.rmtree(Path(work), ignore_errors=True)
    return fmu
