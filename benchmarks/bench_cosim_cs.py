"""Co-Simulation FMUs coupled at a fixed step: heliostep beside libcosim (prints figures; not a test).

    .venv/bin/python benchmarks/bench_cosim_cs.py [--repeat 3] [--stop 10] [--steps 1e-3,5e-4,2.5e-4,1e-4]

The system: a two-mass oscillator split into two FMI 2.0 Co-Simulation FMUs that heliostep did not
write (the tests' mini ``Oscillator``, ``tests/data/mini/oscillator.c``, compiled here;
``tests/support/two_oscillators.py``), coupled at h over ``--stop`` seconds by heliostep's sampled
components and by libcosim's fixed-step algorithm (``libcosimpy``, the test extras), in this process,
alternating. Printed per h, best of ``--repeat``: the communication points, each master's wall time
(heliostep's ``simulate``, libcosim's ``simulate_until``), their ratio, the largest difference of the
outputs at the points; then each master's cost for 10x the points (the smallest h's time over the one
ten times larger, where both are run), and one line for scripts:
``cs: h <h> heliostep <s> s, libcosim <s> s, ratio <r>; 10x points: heliostep <r> x, libcosim <r> x``.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests" / "support"))

import two_oscillators  # noqa: E402  (the system and both masters' runs)


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
        print(f"{'h [s]':>8} {'points':>7} {'heliostep [s]':>14} {'libcosim [s]':>13} {'ratio':>6} {'max |diff|':>11}")
        for h in steps:
            helio, cosim = [], []
            for _ in range(args.repeat):
                wall, times, ours = two_oscillators.run_heliostep(fmus, h, args.stop)
                helio.append(wall)
                wall, _, theirs = two_oscillators.run_libcosim(fmus, h, args.stop)
                cosim.append(wall)
            best[h] = (min(helio), min(cosim))
            n = min(len(ours), len(theirs))
            diff = float(np.max(np.abs(ours[:n] - theirs[:n])))
            ratio = best[h][0] / best[h][1]
            print(f"{h:8.2g} {len(times):7d} {best[h][0]:14.3f} {best[h][1]:13.3f} {ratio:6.2f} {diff:11.2g}")
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
