"""Build the FMI 3.0 Co-Simulation test FMU of ``tests/data/mini3cs/`` (``lag3.c``; every FMI 3.0 function it
does not define from ``tests/data/mini3/fmi3_stubs.c``).

Lag3 is a first-order lag T dy/dt = u - y, e = u - y, exporting FMI 3.0 Model Exchange and
Co-Simulation from one binary (its fmi3DoStep: RK4 at the internal step h_int, the input held): the
CS FMU and its ME twin. :func:`build_lag3_fmu` compiles it with gcc against the FMI 3.0 headers fmpy
ships (as ``tests/support/third_party_fmu3.py`` does for ``tests/data/mini3/``) and packs it with the
``modelDescription.xml`` of :func:`lag3_model_description`; with ``sources_only`` it packs no binary,
only ``sources/`` with FMI 3.0's ``sources/buildDescription.xml`` (a source FMU). Zip entries carry a
fixed time stamp, so the same arguments give the same bytes. No binary is committed.
"""

from __future__ import annotations

import subprocess
import tempfile
import zipfile
from pathlib import Path

from third_party_fmu3 import CFLAGS, FMI3_STUBS, fmi3_headers

MINI3CS_DIR = Path(__file__).parents[1] / "data" / "mini3cs"
LAG3_TOKEN = "{c0a7e1f2-3101-4000-8000-000000000101}"
SOURCES = ("lag3.c", FMI3_STUBS.name)
_FIXED_TIME = (1980, 1, 1, 0, 0, 0)

#: (name, type, causality, variability, start); each value reference is the index
LAG3_VARIABLES = (
    ("time", "Float64", "independent", "continuous", None),
    ("u", "Float64", "input", "continuous", "0"),
    ("y", "Float64", "output", "continuous", "0"),
    ("der(y)", "Float64", "local", "continuous", None),
    ("e", "Float64", "output", "continuous", None),
    ("T", "Float64", "parameter", "fixed", "0.5"),
    ("h_int", "Float64", "parameter", "fixed", "0.001"),
    ("t_stop", "Float64", "parameter", "fixed", "1e9"),
    ("misbehave", "Int32", "parameter", "fixed", "0"),
)


def lag3_model_description(
    interfaces: tuple[str, ...] = ("ModelExchange", "CoSimulation"), variable_steps: bool = True
) -> str:
    """Lag3's FMI 3.0 ``modelDescription.xml`` with the interface elements ``interfaces`` (its
    CoSimulation element saying canHandleVariableCommunicationStepSize="true" with ``variable_steps``)."""
    variable = ' canHandleVariableCommunicationStepSize="true"' if variable_steps else ""
    elements = {
        "ModelExchange": '  <ModelExchange modelIdentifier="Lag3"/>',
        "CoSimulation": f'  <CoSimulation modelIdentifier="Lag3"{variable}/>',
    }
    lines = []
    for vr, (name, type_, causality, variability, start) in enumerate(LAG3_VARIABLES):
        attributes = f'name="{name}" valueReference="{vr}" causality="{causality}" variability="{variability}"'
        if start is not None:
            attributes += f' start="{start}"' + (' initial="exact"' if causality == "output" else "")
        if name == "der(y)":
            attributes += ' derivative="2"'
        lines.append(f"    <{type_} {attributes}/>")
    return "\n".join(
        [
            '<?xml version="1.0" encoding="UTF-8"?>',
            f'<fmiModelDescription fmiVersion="3.0" modelName="Lag3" instantiationToken="{LAG3_TOKEN}">',
            *(elements[kind] for kind in interfaces),
            "  <ModelVariables>",
            *lines,
            "  </ModelVariables>",
            "  <ModelStructure>",
            '    <Output valueReference="2" dependencies="2"/>',  # y: the state only
            '    <Output valueReference="4" dependencies="1 2"/>',  # e = u - y: direct feedthrough of u
            '    <ContinuousStateDerivative valueReference="3" dependencies="1 2"/>',
            "  </ModelStructure>",
            "</fmiModelDescription>",
            "",
        ]
    )


BUILD_DESCRIPTION = "\n".join(
    [
        '<?xml version="1.0" encoding="UTF-8"?>',
        '<fmiBuildDescription fmiVersion="3.0">',
        '  <BuildConfiguration modelIdentifier="Lag3">',
        '    <SourceFileSet language="C99">',
        *(f'      <SourceFile name="{name}"/>' for name in SOURCES),
        "    </SourceFileSet>",
        "  </BuildConfiguration>",
        "</fmiBuildDescription>",
        "",
    ]
)


def _write(archive: zipfile.ZipFile, name: str, data: bytes | str) -> None:
    archive.writestr(zipfile.ZipInfo(name, _FIXED_TIME), data, zipfile.ZIP_DEFLATED)


def build_lag3_fmu(
    out_dir: Path,
    interfaces: tuple[str, ...] = ("ModelExchange", "CoSimulation"),
    sources_only: bool = False,
    source_edit: tuple[str, str] | None = None,
    name: str = "Lag3",
    variable_steps: bool = True,
) -> Path:
    """``out_dir/<name>.fmu``: Lag3 with the ``interfaces`` given, compiled (or, with ``sources_only``,
    its sources and buildDescription.xml only); ``source_edit`` (old, new) replaces text in lag3.c."""
    source = (MINI3CS_DIR / "lag3.c").read_text()
    if source_edit is not None:
        assert source_edit[0] in source
        source = source.replace(*source_edit)
    out_dir.mkdir(parents=True, exist_ok=True)
    fmu = out_dir / f"{name}.fmu"
    with tempfile.TemporaryDirectory() as work:
        (Path(work) / "lag3.c").write_text(source)
        library = Path(work) / "Lag3.so"
        if not sources_only:
            command = ["gcc", *CFLAGS, f"-I{fmi3_headers()}", "-o", str(library), str(Path(work) / "lag3.c")]
            result = subprocess.run(command + [str(FMI3_STUBS), "-lm"], capture_output=True, text=True)
            if result.returncode != 0:
                raise RuntimeError(f"gcc failed for Lag3:\n{result.stderr}")
        with zipfile.ZipFile(fmu, "w") as archive:
            _write(archive, "modelDescription.xml", lag3_model_description(interfaces, variable_steps))
            if not sources_only:
                _write(archive, "binaries/x86_64-linux/Lag3.so", library.read_bytes())
            _write(archive, "sources/lag3.c", source)
            _write(archive, f"sources/{FMI3_STUBS.name}", FMI3_STUBS.read_text())
            if sources_only:
                _write(archive, "sources/buildDescription.xml", BUILD_DESCRIPTION)
    return fmu
