"""What drawing a run's figures costs: the plotting modules' import, and each figure with the text hinted or not.

    .venv/bin/python benchmarks/bench_plots.py [scenario.yaml] [--repeat 3]

The import is timed in fresh interpreters after the command's own modules (median of ``--repeat``); the figures
are drawn one after the other into memory, once per ``text.hinting`` setting, alternating (best of ``--repeat``).
``no_hinting`` is what :func:`heliostep.plots.png.save_png` draws with. First line:
``plots: <s> s, hinted <s> s, import <s> s``.
"""

from __future__ import annotations

import argparse
import io
import statistics
import subprocess
import sys
import time

import matplotlib

from heliostep.paths import scenarios_dir
from heliostep.plots import png
from heliostep.plots.light import light_figure
from heliostep.plots.run import _DPI, run_figures
from heliostep.results.light.on_tube import light_timeseries
from heliostep.run import run_scenario

SETTINGS = ("no_hinting", "default", "auto")
POWER = "power_on_tube.png"
IMPORT = (
    "import time, heliostep.cli.run; start = time.perf_counter(); import heliostep.plots.run, heliostep.plots.light; "
    "print(time.perf_counter() - start)"
)


def import_time(repeat: int) -> float:
    """The plotting modules' import [s] after the command's own, median over fresh interpreters."""
    times = [float(subprocess.check_output([sys.executable, "-c", IMPORT], text=True)) for _ in range(repeat)]
    return statistics.median(times)


def save(figure) -> None:
    """The figure written as a PNG into memory, as :func:`heliostep.plots.png.save_png` writes it."""
    figure.savefig(io.BytesIO(), format="png", dpi=_DPI, pil_kwargs=png.PNG_OPTIONS)


def draw_all(result) -> dict[str, float]:
    """Each figure's time [s] (built and written as a PNG into memory) with the current rcParams."""
    times = {}
    for name, figure in run_figures(result.trace, result.trace_metadata(), result.solution_plot):
        started = time.perf_counter()
        if figure is not None:
            save(figure)
        times[name] = time.perf_counter() - started
    started = time.perf_counter()
    series = light_timeseries(result.trace, result.metadata, result.scenario, result.weather)
    save(light_figure(series, result.metadata, "", result.summary))
    times[POWER] = time.perf_counter() - started
    return times


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("scenario", nargs="?", default=str(scenarios_dir() / "jan21-central.yaml"))
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args(argv)
    imported = import_time(args.repeat)
    result = run_scenario(args.scenario)
    best: dict[str, dict[str, float]] = {setting: {} for setting in SETTINGS}
    draw_all(result)  # the first use of the fonts, for every setting alike
    for _ in range(args.repeat):
        for setting in SETTINGS:
            with matplotlib.rc_context({"text.hinting": setting}):
                for name, seconds in draw_all(result).items():
                    best[setting][name] = min(seconds, best[setting].get(name, float("inf")))
    totals = {setting: sum(best[setting].values()) for setting in SETTINGS}
    print(f"plots: {totals['no_hinting']:.3f} s, hinted {totals['default']:.3f} s, import {imported:.3f} s")
    print(f"{'figure':32s}" + "".join(f"{setting:>12s}" for setting in SETTINGS))
    for name in best["no_hinting"]:
        print(f"{name:32s}" + "".join(f"{best[setting][name]:12.3f}" for setting in SETTINGS))
    print(f"{'all, one after the other':32s}" + "".join(f"{totals[setting]:12.3f}" for setting in SETTINGS))
    print(f"the plotting modules' import after the command's (median of {args.repeat} interpreters): {imported:.3f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
