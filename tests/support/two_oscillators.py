"""A two-mass oscillator split into two Co-Simulation FMUs, run by heliostep and by libcosim.

Two instances of the mini ``Oscillator`` (``tests/data/mini/oscillator.c``, FMI 2.0 CS, RK4 inside its
``fmi2DoStep``): ``a`` (a mass on a wall spring, displaced to x0, pushed by ``b.F_c``) and ``b`` (a mass
on a wall spring and the coupling spring-damper to ``a``, reading ``a.x`` and ``a.v``). Both masters
couple them at a fixed step h (Jacobi: both step from t_k with the inputs of t_k, then the outputs
go to the inputs): heliostep's sampled components (:func:`run_heliostep`) and libcosim's fixed-step
algorithm through libcosimpy (:func:`run_libcosim`), each giving the values at every communication point.
"""

from __future__ import annotations

import shutil
import time
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from third_party_fmu import MINI_FMUS, build_mini_fmu

#: parameters per instance
PARAMETERS = {
    "a": {"m": 1.0, "c": 100.0, "d": 0.2, "x0": 0.1},
    "b": {"m": 2.0, "c": 60.0, "d": 0.1, "c_c": 50.0, "d_c": 0.5},
}
#: output -> input
CONNECTIONS = [("a.x", "b.x_in"), ("a.v", "b.v_in"), ("b.F_c", "a.F")]
#: the outputs compared, in this order
OUTPUTS = ("a.x", "a.v", "b.x", "b.v", "b.F_c")


def build(out: Path) -> dict[str, Path]:
    """Instance -> FMU file: the Oscillator FMU compiled into ``out``, and a copy of it for ``b`` (two FMU
    files, as two FMUs from elsewhere would be)."""
    fmu = build_mini_fmu("Oscillator", out)
    copy = out / "OscillatorB.fmu"
    shutil.copyfile(fmu, copy)
    return {"a": fmu, "b": copy}


def run_heliostep(fmus: Mapping[str, Path], h: float, stop: float) -> tuple[float, np.ndarray, np.ndarray]:
    """heliostep's run: (wall time of ``simulate`` [s], the communication points k h [s] (k = 1, 2, ...),
    the outputs there: one column per :data:`OUTPUTS`, the values after each point's step)."""
    from heliostep.cosim import Connection, CoSimulation, read_fmu

    system = CoSimulation(
        {name: read_fmu(path, co_simulation=True) for name, path in fmus.items()},
        [Connection(s, t) for s, t in CONNECTIONS],
        parameters=PARAMETERS,
        communication_intervals={"a": h, "b": h},
    )
    started = time.perf_counter()
    result = system.simulate(0.0, stop)
    wall = time.perf_counter() - started
    trace = result.trace
    times = trace["time"].to_numpy()
    last = np.r_[times[1:] != times[:-1], True] & (times > 0.0)  # the row after each point's event
    return wall, times[last], trace.loc[last, list(OUTPUTS)].to_numpy()


def run_libcosim(fmus: Mapping[str, Path], h: float, stop: float) -> tuple[float, np.ndarray, np.ndarray]:
    """libcosim's run (``libcosimpy``, its fixed-step algorithm at ``h``): the same as :func:`run_heliostep`."""
    from libcosimpy.CosimEnums import CosimVariableType
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
    from libcosimpy.CosimObserver import CosimObserver
    from libcosimpy.CosimSlave import CosimLocalSlave

    log_output_level(CosimLogLevel.WARNING)  # its default prints every FMI Library step to stderr

    refs = {v[0]: k for k, v in enumerate(MINI_FMUS["Oscillator"][3])}
    nanos = round(h * 1e9)
    steps = round(stop * 1e9) // nanos
    execution = CosimExecution.from_step_size(nanos)
    index = {}
    for name in ("a", "b"):
        index[name] = execution.add_local_slave(CosimLocalSlave(fmu_path=str(fmus[name]), instance_name=name))
        for parameter, value in PARAMETERS[name].items():
            execution.real_initial_value(index[name], refs[parameter], value)
    for source, target in CONNECTIONS:
        (s, sv), (t, tv) = source.split("."), target.split(".")
        execution.connect_real_variables(index[s], refs[sv], index[t], refs[tv])
    observer = CosimObserver.create_time_series(buffer_size=steps + 2)
    execution.add_observer(observer)
    columns = [(index[n], refs[v]) for n, v in (o.split(".") for o in OUTPUTS)]
    for slave, ref in columns:
        observer.start_time_series(slave, ref, CosimVariableType.REAL)
    started = time.perf_counter()
    execution.simulate_until(round(stop * 1e9))
    wall = time.perf_counter() - started
    values = []
    for slave, ref in columns:  # from step 1: libcosimpy drops a sample per step number 0 it returns
        nanos_at, _, samples = observer.time_series_real_samples(slave, ref, from_step=1, sample_count=steps)
        values.append(samples)
    return wall, np.asarray(nanos_at) * 1e-9, np.array(values).T
