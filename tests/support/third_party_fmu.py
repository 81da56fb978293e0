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

SOURCE_DIR = Path(__file__).parents[1] / "data" / "bouncing_ball"
MODEL_IDENTIFIER = "BouncingBall"
CFLAGS = ["-std=c99", "-O2", "-fPIC", "-shared", "-fvisibility=hidden", "-Wall", "-Wextra", "-Werror"]

#: value references, as in modelDescription.xml
VR = {
    "time": 0,
    "h": 1,
    "der(h)": 2,
    "v": 3,
    "der(v)": 4,
    "g": 5,
    "e": 6,
    "h0": 7,
    "t_kick": 8,
    "f": 9,
    "height": 10,
    "bounce_count": 11,
}


def fmi2_headers() -> Path:
    """The folder of the FMI 2.0 C headers that fmpy ships."""
    import fmpy

    return Path(fmpy.__file__).parent / "c-code"


def build_bouncing_ball(out_dir: Path) -> Path:
    """Compile ``BouncingBall`` and pack it as ``out_dir/BouncingBall.fmu``; return that path.

    Raises :class:`RuntimeError` with gcc's output when the compilation fails.
    """
    return _compile_and_pack(
        MODEL_IDENTIFIER,
        [SOURCE_DIR / "bouncing_ball.c"],
        [],
        (SOURCE_DIR / "modelDescription.xml").read_text(),
        out_dir,
    )


# ---------------------------------------------------------------------- the mini FMUs
#: Small hand-written FMUs in ``tests/data/mini/`` (C sources sharing ``mini_fmu.h``); their
#: modelDescription.xml is written from these tables by :func:`build_mini_fmu`.
#: Each variable: (name, type, causality, variability, start or None, derivative-of or None);
#: its value reference is its index (as in the C source).
MINI_DIR = Path(__file__).parents[1] / "data" / "mini"
MINI_FMUS = {
    "Counter": (
        "counter.c",
        "{c0a7e1f2-0001-4000-8000-000000000001}",
        0,
        [
            ("count", "Integer", "output", "discrete", None, None),
            ("x", "Real", "output", "continuous", 0.0, None),
            ("der(x)", "Real", "local", "continuous", None, "x"),
            ("period", "Real", "parameter", "fixed", 1.0, None),
            ("t_stop", "Real", "parameter", "fixed", 9.0, None),
            ("half", "Real", "output", "discrete", None, None),
            ("even", "Boolean", "output", "discrete", None, None),
            ("step", "Integer", "parameter", "fixed", 1, None),
            ("enabled", "Boolean", "parameter", "fixed", True, None),
            ("ticks", "Integer", "local", "discrete", None, None),
            ("rate", "Real", "parameter", "fixed", 0.0, None),
        ],
    ),
    "PassThrough": (
        "pass_through.c",
        "{c0a7e1f2-0002-4000-8000-000000000002}",
        0,
        [
            ("u_c", "Real", "input", "continuous", 0.0, None),
            ("u_d", "Real", "input", "discrete", 0.0, None),
            ("u_i", "Integer", "input", "discrete", 0, None),
            ("u_b", "Boolean", "input", "discrete", False, None),
            ("y_c", "Real", "output", "continuous", None, None),
            ("y_d", "Real", "output", "discrete", None, None),
            ("y_i", "Integer", "output", "discrete", None, None),
            ("y_b", "Boolean", "output", "discrete", None, None),
            ("integral", "Real", "output", "continuous", 0.0, None),
            ("der(integral)", "Real", "local", "continuous", None, "integral"),
            ("u_max", "Real", "parameter", "fixed", 1e300, None),
        ],
    ),
    "Switch": (
        "switch.c",
        "{c0a7e1f2-0003-4000-8000-000000000003}",
        1,
        [
            ("x", "Real", "output", "continuous", 0.0, None),
            ("der(x)", "Real", "local", "continuous", None, "x"),
            ("on", "Boolean", "output", "discrete", None, None),
            ("switches", "Integer", "output", "discrete", None, None),
            ("up", "Real", "parameter", "fixed", 1.0, None),
            ("down", "Real", "parameter", "fixed", 2.0, None),
            ("high", "Real", "parameter", "fixed", 1.0, None),
        ],
    ),
    "Gain": (
        "gain.c",
        "{c0a7e1f2-0004-4000-8000-000000000004}",
        0,
        [
            ("u", "Real", "input", "continuous", 0.0, None),
            ("y", "Real", "output", "continuous", None, None),
            ("k", "Real", "parameter", "fixed", 0.5, None),
            ("b", "Real", "parameter", "fixed", 1.0, None),
            ("s", "Real", "output", "continuous", 0.0, None),
            ("der(s)", "Real", "local", "continuous", None, "s"),
            ("a", "Real", "parameter", "fixed", 0.0, None),
            ("c", "Real", "input", "continuous", 0.0, None),
        ],
    ),
    "Rescale": (
        "rescale.c",
        "{c0a7e1f2-0005-4000-8000-000000000005}",
        0,
        [
            ("x", "Real", "output", "continuous", 1.0, None),
            ("der(x)", "Real", "local", "continuous", None, "x"),
            ("period", "Real", "parameter", "fixed", 0.25, None),
            ("t_switch", "Real", "parameter", "fixed", 1.0, None),
            ("small", "Real", "parameter", "fixed", 1e-4, None),
            ("nominal_reads", "Integer", "output", "discrete", None, None),
            ("switched", "Boolean", "output", "discrete", None, None),
        ],
    ),
    "Faulty": (  # crashes, exits or hangs on request (tests of supervised runs)
        "faulty.c",
        "{c0a7e1f2-0006-4000-8000-000000000006}",
        0,
        [
            ("x", "Real", "output", "continuous", 0.0, None),
            ("der(x)", "Real", "local", "continuous", None, "x"),
            ("fault", "Integer", "parameter", "fixed", 0, None),
            ("t_fault", "Real", "parameter", "fixed", 1.0, None),
            ("period", "Real", "parameter", "fixed", 0.5, None),
        ],
    ),
    "Lag": (  # exported for Model Exchange and Co-Simulation: the tests' CS FMU and its ME twin
        "lag.c",
        "{c0a7e1f2-0007-4000-8000-000000000007}",
        0,
        [
            ("u", "Real", "input", "continuous", 0.0, None),
            ("y", "Real", "output", "continuous", 0.0, None),
            ("e", "Real", "output", "continuous", None, None),
            ("der(y)", "Real", "local", "continuous", None, "y"),
            ("T", "Real", "parameter", "fixed", 0.5, None),
        ],
    ),
    "LagStop": (  # the Lag whose Co-Simulation step stops at t_stop: fmi2Discard, then fmi2Terminated
        "lag_stop.c",
        "{c0a7e1f2-0008-4000-8000-000000000008}",
        0,
        [
            ("u", "Real", "input", "continuous", 0.0, None),
            ("y", "Real", "output", "continuous", 0.0, None),
            ("e", "Real", "output", "continuous", None, None),
            ("der(y)", "Real", "local", "continuous", None, "y"),
            ("T", "Real", "parameter", "fixed", 0.5, None),
            ("t_stop", "Real", "parameter", "fixed", 1e300, None),
            ("says_terminated", "Integer", "parameter", "fixed", 1, None),
        ],
    ),
    "Oscillator": (  # a mass on a spring, pushed by F, with a coupling force F_c to another: two make a system
        "oscillator.c",
        "{c0a7e1f2-0009-4000-8000-000000000009}",
        0,
        [
            ("F", "Real", "input", "continuous", 0.0, None),
            ("x_in", "Real", "input", "continuous", 0.0, None),
            ("v_in", "Real", "input", "continuous", 0.0, None),
            ("x", "Real", "output", "continuous", None, None),
            ("v", "Real", "output", "continuous", 0.0, None),
            ("F_c", "Real", "output", "continuous", None, None),
            ("der(x)", "Real", "local", "continuous", None, "x"),
            ("der(v)", "Real", "local", "continuous", None, "v"),
            ("m", "Real", "parameter", "fixed", 1.0, None),
            ("c", "Real", "parameter", "fixed", 100.0, None),
            ("d", "Real", "parameter", "fixed", 0.0, None),
            ("c_c", "Real", "parameter", "fixed", 0.0, None),
            ("d_c", "Real", "parameter", "fixed", 0.0, None),
            ("x0", "Real", "parameter", "fixed", 0.0, None),
        ],
    ),
}
#: direct feedthrough: model -> output -> the inputs it depends on
_FEEDTHROUGH = {
    "PassThrough": {"y_c": ("u_c",), "y_d": ("u_d",), "y_i": ("u_i",), "y_b": ("u_b",)},
    "Gain": {"y": ("u", "c")},
    "Lag": {"e": ("u",)},
    "LagStop": {"e": ("u",)},
    "Oscillator": {"F_c": ("x_in", "v_in")},
}
#: the mini FMUs whose modelDescription.xml also declares Co-Simulation (fmi2DoStep in mini_fmu.h)
CO_SIMULATION = {"Lag", "LagStop", "Oscillator"}


def _model_description(name: str) -> str:
    _, guid, n_indicators, variables = MINI_FMUS[name]
    index = {v[0]: k + 1 for k, v in enumerate(variables)}
    lines = [
        '<?xml version="1.0" encoding="UTF-8"?>',
        f'<fmiModelDescription fmiVersion="2.0" modelName="{name}" guid="{guid}" '
        f'numberOfEventIndicators="{n_indicators}" variableNamingConvention="structured">',
        f'  <ModelExchange modelIdentifier="{name}"/>',
        *(
            [f'  <CoSimulation modelIdentifier="{name}" canHandleVariableCommunicationStepSize="true"/>']
            * (name in CO_SIMULATION)
        ),
        "  <ModelVariables>",
    ]
    for vr, (var, type_, causality, variability, start, derivative) in enumerate(variables):
        attributes = f'name="{var}" valueReference="{vr}" causality="{causality}" variability="{variability}"'
        if start is not None and causality in ("output", "local"):
            attributes += ' initial="exact"'
        element = ""
        if start is not None:
            text = str(start).lower() if type_ == "Boolean" else repr(start)
            element += f' start="{text}"'
        if derivative:
            element += f' derivative="{index[derivative]}"'
        lines.append(f"    <ScalarVariable {attributes}><{type_}{element}/></ScalarVariable>")
    lines += ["  </ModelVariables>", "  <ModelStructure>", "    <Outputs>"]
    for var, *_ in (v for v in variables if v[2] == "output"):
        sources = _FEEDTHROUGH.get(name, {}).get(var, ())
        deps = f' dependencies="{" ".join(str(index[source]) for source in sources)}"'
        lines.append(f'      <Unknown index="{index[var]}"{deps}/>')
    lines += ["    </Outputs>", "    <Derivatives>"]
    derivatives = [v for v in variables if v[5]]
    for var, *_ in derivatives:
        lines.append(f'      <Unknown index="{index[var]}"/>')
    lines += ["    </Derivatives>", "    <InitialUnknowns>"]
    for var, _type, causality, _variability, start, derivative in variables:
        if (causality == "output" and start is None) or derivative:
            lines.append(f'      <Unknown index="{index[var]}"/>')
    lines += ["    </InitialUnknowns>", "  </ModelStructure>", "</fmiModelDescription>", ""]
    return "\n".join(lines)


def build_mini_fmu(name: str, out_dir: Path, platform: str = "linux64") -> Path:
    """Compile the mini FMU ``name`` (one of :data:`MINI_FMUS`) into ``out_dir/<name>.fmu``."""
    return _compile_and_pack(
        name, [MINI_DIR / MINI_FMUS[name][0]], [MINI_DIR], _model_description(name), out_dir, platform
    )


def build_cs_only_mini_fmu(name: str, out_dir: Path, step_size: float | None) -> Path:
    """The mini FMU ``name`` (one of :data:`CO_SIMULATION`) as an FMU from a tool that exports Co-Simulation
    only, its DefaultExperiment suggesting ``step_size`` [s] (None: no DefaultExperiment), in ``out_dir``."""
    description = _model_description(name).replace(f'  <ModelExchange modelIdentifier="{name}"/>\n', "")
    if step_size is not None:
        description = description.replace(
            "  <ModelVariables>", f'  <DefaultExperiment startTime="0" stepSize="{step_size!r}"/>\n  <ModelVariables>'
        )
    return _compile_and_pack(name, [MINI_DIR / MINI_FMUS[name][0]], [MINI_DIR], description, out_dir)


def _compile_and_pack(
    identifier: str, sources, includes, model_description: str, out_dir: Path, platform: str = "linux64"
) -> Path:
    """Compile ``sources`` with gcc against fmpy's FMI headers and pack ``out_dir/<identifier>.fmu``.

    Raises :class:`RuntimeError` with gcc's output when the compilation fails.
    """
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    fmu_path = out_dir / f"{identifier}.fmu"
    with tempfile.TemporaryDirectory(dir=out_dir) as tmp:
        library = Path(tmp) / f"{identifier}.so"
        gcc = shutil.which("gcc") or "gcc"
        command = [
            gcc,
            *CFLAGS,
            "-I",
            str(fmi2_headers()),
            *[arg for folder in includes for arg in ("-I", str(folder))],
            *map(str, sources),
            "-o",
            str(library),
            "-lm",
        ]
        completed = subprocess.run(command, capture_output=True, text=True)
        if completed.returncode != 0:
            raise RuntimeError(
                f"compiling {identifier} failed:\n{' '.join(command)}\n{completed.stdout}{completed.stderr}"
            )
        partial = Path(tmp) / fmu_path.name
        with zipfile.ZipFile(partial, "w", zipfile.ZIP_DEFLATED) as fmu:
            fmu.writestr("modelDescription.xml", model_description)
            fmu.write(library, f"binaries/{platform}/{identifier}.so")
        partial.replace(fmu_path)  # atomic: a reader never sees a half-written FMU
    return fmu_path
