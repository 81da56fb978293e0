"""Co-Simulation FMUs coupled at a fixed step: heliostep beside libcosim (prints figures; not a test).

    .venv/bin/python benchmarks/bench_cosim_cs.py [--repeat 3] [--stop 10] [--steps 1e-3,5e-4,2.5e-4,1e-4]

The system: a two-mass oscillator split into two FMI 2.0 Co-Simulation FMUs that heliostep did not
write (the tests' mini ``Oscillator``, ``tests/data/mini/oscillator.c``, compiled here;
``tests/support/two_oscillators.py``), coupled at h over ``--stop`` seconds by heliostep's sampled
components and by libcosim's fixed-step algorithm (``libcosimpy``, the test extras), in this process,
alternating. Printed per h, best of ``--repeat``: the communication points, each master's wall time
(heliostep's ``simulate``, libcosim's ``simulate_until``), their ratio, the floor of a master in Python
(heliostep's own FMI 2.0 Co-Simulation instances stepped in a bare loop: the same FMI calls per point and
two trace rows, nothing else), the largest difference of the outputs at the points; then each master's
cost for 10x the points (the smallest h's time over the one ten times larger, where both are run), and
one line for scripts:
``cs: h <h> heliostep <s> s, libcosim <s> s, ratio <r>; 10x points: heliostep <r> x, libcosim <r> x``.
"""

from __future__ import annotations

import argparse
import ctypes
import functools
import shutil
import sys
import tempfile
import time
from collections.abc import Mapping
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests" / "support"))

import two_oscillators  # noqa: E402  (the system and both masters' runs)
from third_party_fmu import MINI_FMUS  # noqa: E402
from two_oscillators import CONNECTIONS, PARAMETERS  # noqa: E402


def run_floor(fmus: Mapping[str, Path], h: float, stop: float) -> float:
    """The floor of a master in Python: the two FMUs instantiated by fmpy, then stepped at h in a bare loop of
    FMI calls bound once with ctypes (per point: both ``fmi2DoStep``, both outputs read with ``fmi2GetReal``,
    both inputs set with ``fmi2SetReal``, two trace rows written), nothing else; its wall time [s]."""
    from fmpy import extract, read_model_description
    from fmpy.fmi2 import FMU2Slave

    refs = {v[0]: k for k, v in enumerate(MINI_FMUS["Oscillator"][3])}
    values = ctypes.CFUNCTYPE(ctypes.c_int, ctypes.c_void_p, ctypes.c_void_p, ctypes.c_size_t, ctypes.c_void_p)
    do_step = ctypes.CFUNCTYPE(ctypes.c_int, ctypes.c_void_p, ctypes.c_double, ctypes.c_double, ctypes.c_int)
    slaves, folders, calls, keep = {}, [], {}, []
    for name, path in fmus.items():
        folders.append(extract(str(path)))
        guid = read_model_description(str(path)).guid
        slave = FMU2Slave(guid=guid, unzipDirectory=folders[-1], modelIdentifier="Oscillator", instanceName=name)
        slave.instantiate()
        slave.setupExperiment(startTime=0.0, stopTime=stop)
        slave.enterInitializationMode()
        slave.setReal([refs[p] for p in PARAMETERS[name]], list(PARAMETERS[name].values()))
        slave.exitInitializationMode()
        slaves[name] = slave
        bound = []
        for function, ends in (
            ("fmi2GetReal", [s for s, _ in CONNECTIONS]),
            ("fmi2SetReal", [t for _, t in CONNECTIONS]),
        ):
            mine = [refs[e.split(".")[1]] for e in ends if e.startswith(f"{name}.")]
            vr, buffer = (ctypes.c_uint32 * len(mine))(*mine), (ctypes.c_double * len(mine))()
            keep.append(vr)
            call = values((function, slave.dll))
            bound.append(
                (
                    functools.partial(call, slave.component, ctypes.addressof(vr), len(mine), ctypes.addressof(buffer)),
                    buffer,
                )
            )
        calls[name] = (functools.partial(do_step(("fmi2DoStep", slave.dll)), slave.component), *bound)
    (step_a, (get_a, out_a), (set_a, in_a)), (step_b, (get_b, out_b), (set_b, in_b)) = calls["a"], calls["b"]
    points = (h * np.arange(1, round(stop / h) + 1)).tolist()
    rows = np.zeros((2 * len(points), 4))
    started = time.perf_counter()
    get_a(), get_b()
    previous = 0.0
    for k, t in enumerate(points):
        rows[2 * k] = [t, out_a[0], out_a[1], out_b[0]]
        if step_a(previous, t - previous, 1) or step_b(previous, t - previous, 1) or get_a() or get_b():
            raise RuntimeError(f"an FMI call failed at t = {t} s")
        in_a[0] = out_b[0]  # a.F <- b.F_c
        in_b[0], in_b[1] = out_a[0], out_a[1]  # b.x_in, b.v_in <- a.x, a.v
        if set_a() or set_b():
            raise RuntimeError(f"an FMI call failed at t = {t} s")
        rows[2 * k + 1] = [t, out_a[0], out_a[1], out_b[0]]
        previous = t
    wall = time.perf_counter() - started
    for slave in slaves.values():
        slave.terminate()
        slave.freeInstance()
    for folder in folders:
        shutil.rmtree(folder, ignore_errors=True)
    return wall


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--stop", type=float, default=10.0, help="the simulated time [s]")
    parser.add_argument("--steps", default="1e-3,5e-4,2.5e-4,1e-4", help="communication steps h [s]")
    args = parser.parse_args()
    steps = [float(h) for h in args.steps.split(",")]

    with tempfile.TemporaryDirectory() as tmp:
        fmus = two_oscillators.build(Path(tmp))
        best: dict[float, tuple[float, float]] = {}
        print(
            f"{'h [s]':>8} {'points':>7} {'heliostep [s]':>14} {'libcosim [s]':>13} {'ratio':>6} {'floor [s]':>10} "
            f"{'max |diff|':>11}"
        )
        for h in steps:
            helio, cosim, floor = [], [], []
            for _ in range(args.repeat):
                wall, times, ours = two_oscillators.run_heliostep(fmus, h, args.stop)
                helio.append(wall)
                wall, _, theirs = two_oscillators.run_libcosim(fmus, h, args.stop)
                cosim.append(wall)
                floor.append(run_floor(fmus, h, args.stop))
            best[h] = (min(helio), min(cosim))
            diff = float(np.max(np.abs(ours - theirs)))
            ratio = best[h][0] / best[h][1]
            print(
                f"{h:8.2g} {len(times):7d} {best[h][0]:14.3f} {best[h][1]:13.3f} {ratio:6.2f} {min(floor):10.3f} "
                f"{diff:11.2g}"
            )
    smallest = min(steps)
    coarse = [h for h in steps if np.isclose(h, 10 * smallest)]
    helio_x = cosim_x = float("nan")
    if coarse:
        helio_x = best[smallest][0] / best[coarse[0]][0]
        cosim_x = best[smallest][1] / best[coarse[0]][1]
        span = f"{coarse[0]:g} s -> {smallest:g} s"
        print(f"10x the points ({span}): heliostep {helio_x:.1f} x, libcosim {cosim_x:.1f} x")
    helio, cosim = best[smallest]
    print(
        f"cs: h {smallest:g} heliostep {helio:.3f} s, libcosim {cosim:.3f} s, ratio {helio / cosim:.2f}; "
        f"10x points: heliostep {helio_x:.1f} x, libcosim {cosim_x:.1f} x"
    )


if __name__ == "__main__":
    main()
