"""The co-simulated pull-out curve of the Applied Motion HT34-504 beside its measured one.

    .venv/bin/python benchmarks/pull_out_measured.py [--tolerance 0.02]

At the measured points from 500 to 6 000 full steps/s, on 24, 48 and 75 V, each bus at the band's weak
corner (largest R and detent torque) and strong corner (smallest): [N.m] and normalised to the plateau
(the pull-out at 500 full steps/s). The data and the bands: tests/support/measured_pull_out.py; the
comparison: docs/sizing.md. Not a test (72 bisections: a few minutes).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests" / "support"))

from heliostep.run.speed_torque import BENCH_LOAD_INERTIA, bench_fmus, speed_torque_curve  # noqa: E402
from measured_pull_out import (  # noqa: E402
    BUSES,
    DETENT_BAND,
    MEASURED_PLATEAU,
    MEASURED_RPM,
    MODE,
    RATED_CURRENT,
    RESISTANCE_BAND,
    band_corners,
    full_steps_per_s,
    measured_at,
)

RATES = [full_steps_per_s(rpm) for rpm in MEASURED_RPM if 500 <= full_steps_per_s(rpm) <= 6000]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--tolerance", type=float, default=0.02, help="bisection tolerance (of the holding torque)")
    tolerance = parser.parse_args().tolerance
    print(
        f"HT34-504, {MODE}, {RATED_CURRENT} A; R {RESISTANCE_BAND[0]:.3f}-{RESISTANCE_BAND[1]:.3f} Ohm, "
        f"T_d {DETENT_BAND[0]:.4f}-{DETENT_BAND[1]:.4f} N.m; load inertia {BENCH_LOAD_INERTIA:.3g} kg.m2; "
        f"bisection to {tolerance:g}"
    )
    fmus = bench_fmus()
    columns = {}
    for bus in BUSES:
        for corner, drive in band_corners(bus).items():
            curve = speed_torque_curve(drive, RATED_CURRENT, RATES, mode=MODE, tolerance=tolerance, fmus=fmus)
            columns[f"{bus:.0f} V {corner}"] = [curve.at(rate) for rate in RATES]
    measured = [measured_at(rate) for rate in RATES]
    header = f"{'rate [steps/s]':>14} {'rpm':>5} {'measured':>9} " + " ".join(f"{name:>11}" for name in columns)
    for title, scale in (("[N.m]", None), ("normalised to the plateau", 0)):
        print(f"\npull-out torque {title}")
        print(header)
        for k, rate in enumerate(RATES):
            if scale is None:
                cells, own = [values[k] for values in columns.values()], measured[k]
            else:
                cells = [values[k] / values[scale] for values in columns.values()]
                own = measured[k] / MEASURED_PLATEAU
            row = " ".join(f"{value:11.3f}" for value in cells)
            print(f"{rate:14.0f} {rate * 60 / 200:5.0f} {own:9.3f} {row}")


if __name__ == "__main__":
    main()
