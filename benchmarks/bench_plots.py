"""What drawing a run's figures costs: the plotting modules' import, and each figure with the text hinted or not.

    .venv/bin/python benchmarks/bench_plots.py [scenario.yaml] [--repeat 3]

Issue #26's "plots that draw only what they show". First, in fresh interpreters (median of ``--repeat``), the
import of the plotting modules a run's drawer imports (``heliostep.plots.run``, ``heliostep.plots.light``:
matplotlib, its 3-D toolkit, PIL) after the modules the command has already imported
(``heliostep.cli.run``): what the drawer (``heliostep.run.drawing.start_drawer``) takes off the critical path.
Then the scenario (default the paper's 5 minutes) is run once and its 8 figures drawn one after the other in this
process into memory, once per ``text.hinting`` setting, the settings alternating (best of ``--repeat``): each
figure's time and the total (the power on the tube drawn from the run's kept light, ``RunResult.light_rows``, as a
run draws it; beside it, not in the total, the same with the light computed again from the trace). ``no_hinting``
is what :func:`heliostep.plots.png.save_png` draws with; ``default``
runs the font's TrueType hinting program (matplotlib's default), ``auto`` FreeType's auto-hinter. First line,
for scripts: ``plots: <s> s, hinted <s> s, import <s> s``.
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
from heliostep.results.light import light_timeseries
from heliostep.run import run_scenario

SETTINGS = ("no_hinting", "default", "auto")
#: The power on the tube with its light computed again from the trace (as before ``RunResult.light_rows``; a
#: streamed trace's run still does it): shown beside the figures, not added to their total.
AGAIN = "power_on_tube.png, light again"
IMPORT = (
    "import time, heliostep.cli.run; start = time.perf_counter(); import heliostep.plots.run, heliostep.plots.light; "
    "print(time.perf_counter() - start)"
)


def import_time(repeat: int) -> float:
    """The plotting modules' import [s] after the command's own, median over fresh interpreters."""
    times = [float(subprocess.check_output([sys.executable, "-c", IMPORT], text=True)) for _ in range(repeat)]
    return statistics.median(times)


def draw_all(result, job) -> dict[str, float]:
    """Each figure's time [s] (built and written as a PNG into memory) with the current rcParams."""
    times = {}
    for name, figure in run_figures(job.source, job.trace_metadata, job.solution_plot):
        started = time.perf_counter()
        if figure is not None:
            figure.savefig(io.BytesIO(), format="png", dpi=_DPI, pil_kwargs=png.PNG_OPTIONS)
        times[name] = time.perf_counter() - started
    for name, kept in (("power_on_tube.png", True), (AGAIN, False)):
        started = time.perf_counter()
        series = job.light_rows if kept else light_timeseries(job.light, job.metadata, job.scenario, job.weather)
        light_figure(series, job.metadata, "", job.summary).savefig(
            io.BytesIO(), format="png", dpi=_DPI, pil_kwargs=png.PNG_OPTIONS
        )
        times[name] = time.perf_counter() - started
    return times


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("scenario", nargs="?", default=str(scenarios_dir() / "jan21-central.yaml"))
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args(argv)
    imported = import_time(args.repeat)
    result = run_scenario(args.scenario)
    job = result._figure_job()
    best: dict[str, dict[str, float]] = {setting: {} for setting in SETTINGS}
    draw_all(result, job)  # the first use of the fonts, for every setting alike
    for _ in range(args.repeat):
        for setting in SETTINGS:
            with matplotlib.rc_context({"text.hinting": setting}):
                for name, seconds in draw_all(result, job).items():
                    best[setting][name] = min(seconds, best[setting].get(name, float("inf")))
    totals = {setting: sum(t for name, t in best[setting].items() if name != AGAIN) for setting in SETTINGS}
    print(f"plots: {totals['no_hinting']:.3f} s, hinted {totals['default']:.3f} s, import {imported:.3f} s")
    print(f"{'figure':32s}" + "".join(f"{setting:>12s}" for setting in SETTINGS))
    for name in best["no_hinting"]:
        print(f"{name:32s}" + "".join(f"{best[setting][name]:12.3f}" for setting in SETTINGS))
    print(f"{'all, one after the other':32s}" + "".join(f"{totals[setting]:12.3f}" for setting in SETTINGS))
    print(f"the plotting modules' import after the command's (median of {args.repeat} interpreters): {imported:.3f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
