"""Build FMI 3.0 FMUs with PythonFMU3 (``pythonfmu3`` on PyPI), and FMI 2.0 Co-Simulation ones with its
sibling PythonFMU (``pythonfmu``): exporters nobody in heliostep wrote.

PythonFMU3 packs a Python class into an FMU with its own C++ FMI 3.0 layer (a prebuilt binary from its
wheel that runs the class in an embedded interpreter) and its own ``modelDescription.xml``. The
classes are in ``tests/data/pythonfmu3/`` (written for heliostep's tests, in PythonFMU3's style);
:func:`build_pythonfmu3` builds one into a folder. Nothing built is committed.
"""

from __future__ import annotations

from pathlib import Path

SOURCE_DIR = Path(__file__).parents[1] / "data" / "pythonfmu3"

#: the model files and the identifier (class name) PythonFMU3 gives each FMU
MODELS = {
    "lag_me": "PyLag",  # Model Exchange: T dy/dt = u - y
    "counter_me": "PyCounter",  # Model Exchange: Int32 count at time events, terminates at a limit
    "bounce_me": "PyBounce",  # Model Exchange: a state event (x falls to zero, reset to one)
    "types_me": "PyTypes",  # Model Exchange: Int32, Int64, UInt64, Boolean, String, a Float64[3] array
    "pass_me": "PyPass",  # Model Exchange: a pass-through of those types and the array
    "lag_cs": "PyLagCS",  # Co-Simulation: the lag's exact step with its input held
}
#: the FMI 2.0 Co-Simulation models (PythonFMU)
MODELS2 = {"lag2_cs": "PyLag2CS"}  # the lag's exact step; a step past t_stop refused (do_step False)


def build_pythonfmu3(model: str, out_dir: Path) -> Path:
    """Build ``tests/data/pythonfmu3/<model>.py`` with PythonFMU3 into ``out_dir``; the FMU's path."""
    from pythonfmu3.builder import FmuBuilder

    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    built = Path(FmuBuilder.build_FMU(SOURCE_DIR / f"{model}.py", dest=out_dir, needsExecutionTool="false"))
    assert built.name == f"{MODELS[model]}.fmu", built
    return built


def build_pythonfmu(model: str, out_dir: Path) -> Path:
    """Build ``tests/data/pythonfmu3/<model>.py`` with PythonFMU (FMI 2.0 Co-Simulation) into ``out_dir``."""
    from pythonfmu.builder import FmuBuilder

    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    built = Path(FmuBuilder.build_FMU(SOURCE_DIR / f"{model}.py", dest=out_dir))
    assert built.name == f"{MODELS2[model]}.fmu", built
    return built
