"""The whole process of ``heliostep run`` timed from outside, with and without plots (prints figures; not a test).

    .venv/bin/python benchmarks/bench_cli.py [scenario.yaml] [--repeat 5] [--no-breakdown] [--baseline SRC]

Median wall and CPU time (the children's included) of the variants, alternating; bytecode as a user's second run
has it; the first run of each not counted. Then one run's stages timed inside the process and its imports by
package (``-X importtime``). First line: ``run: <s> s, no-plots <s> s``.
"""

from __future__ import annotations

import argparse
import functools
import os
import re
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SCENARIO = ROOT / "scenarios" / "jan21-central.yaml"
#: the installed command's entry point (``[project.scripts]``)
HELIOSTEP = [sys.executable, "-c", "from heliostep.cli import console_main; console_main()"]
#: the third-party modules a ``--no-plots`` run imports (``tests/cli/test_run_imports.py`` checks what it does
#: not), imported alone: what no change to heliostep's own code takes off a run
LIBRARIES = "numpy, pandas, scipy.interpolate, scipy.special, pydantic, yaml, pyarrow.parquet, fmpy.fmi2"
#: the same but pandas (none of the others imports it): what pandas' import adds to every run
LIBRARIES_BUT_PANDAS = ", ".join(name for name in LIBRARIES.split(", ") if name != "pandas")

#: (label, module, attribute) of the functions the breakdown times: leaves of the run's call tree, so no time is
#: counted twice, patched where they are looked up (a function another tree does not have is left out).
STAGES = (
    ("scenario read and checked", "heliostep.cli.run", "load_scenario"),
    ("estimate and budget", "heliostep.cli.run", "estimate_run"),
    ("FMUs resolved (models hashed, cache looked up)", "heliostep.cli.run", "resolve_fmus"),
    ("FMUs read (modelDescription, binary loaded)", "heliostep.run.runner", "read_fmus"),
    ("weather", "heliostep.run.runner", "load_weather"),
    ("drive inputs (sun, reference, step schedule)", "heliostep.run.runner", "prepare_inputs"),
    ("coupled system built", "heliostep.run.runner", "CoSimulation"),
    ("metadata (package versions)", "heliostep.run.runner", "_metadata"),
    ("figure accumulator set up", "heliostep.run.runner", "_run_figures"),
    ("simulation (supervised child, rows fed to the figures)", "heliostep.run.runner", "_co_simulate"),
    ("figures after the simulation (light, summary)", "heliostep.results.figures.run_figures.RunFigures", "summary"),
    ("trace and records written", "heliostep.run.result", "write_run_records"),
    ("plots drawn", "heliostep.run.result.RunResult", "_draw"),
)


def run_once(args: list[str], env: dict | None = None) -> tuple[float, float]:
    """(wall time, CPU time: user + system of the process and its children) [s] of one process (its
    output discarded; a failure stops the benchmark)."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    started = time.perf_counter()
    done = subprocess.run(args, capture_output=True, text=True, env=env)
    wall = time.perf_counter() - started
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if done.returncode != 0:
        raise SystemExit(f"{' '.join(args)} failed ({done.returncode}):\n{done.stderr}")
    return wall, (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def variants(scenario: Path, out: Path, baseline: Path | None = None) -> dict[str, tuple[list[str], dict | None]]:
    """The processes timed side by side: name -> (arguments, environment or None); with ``baseline`` (another
    checkout's ``src``, imported first through ``PYTHONPATH``) its run and no-plots run too."""
    run = [*HELIOSTEP, "run", str(scenario)]
    extra = {}
    if baseline is not None:
        old = {**os.environ, "PYTHONPATH": str(baseline)}
        old_run = [*HELIOSTEP, "run", str(scenario)]
        extra = {
            "run, baseline": ([*old_run, "--out", str(out / "baseline-plots")], old),
            "no-plots, baseline": ([*old_run, "--out", str(out / "baseline-no-plots"), "--no-plots"], old),
        }
    return {
        "run": ([*run, "--out", str(out / "plots")], None),
        "no-plots": ([*run, "--out", str(out / "no-plots"), "--no-plots"], None),
        "no-plots --no-supervise": ([*run, "--out", str(out / "unsupervised"), "--no-plots", "--no-supervise"], None),
        "python -c pass": ([sys.executable, "-c", "pass"], None),
        "the run's libraries alone": ([sys.executable, "-c", f"import {LIBRARIES}"], None),
        "the run's libraries but pandas": (
            [sys.executable, "-c", f"import sys, {LIBRARIES_BUT_PANDAS}; assert 'pandas' not in sys.modules"],
            None,
        ),
        "import pvlib": ([sys.executable, "-c", "import pvlib"], None),
        **extra,
    }


def import_breakdown(scenario: Path, out: Path) -> list[tuple[str, float]]:
    """Self import times [s] summed per top-level package, of a ``--no-plots`` run and a run with plots."""
    rows = []
    for name, extra in (("no-plots", ["--no-plots"]), ("run", [])):
        args = [sys.executable, "-X", "importtime", *HELIOSTEP[1:], "run", str(scenario), "--out", str(out / name)]
        done = subprocess.run([*args, *extra], capture_output=True, text=True)
        totals: dict[str, float] = {}
        for line in done.stderr.splitlines():
            match = re.match(r"import time:\s+(\d+) \|\s+\d+ \|\s*(\S+)", line)
            if match:
                top = match[2].split(".")[0]
                totals[top] = totals.get(top, 0.0) + int(match[1]) * 1e-6
        ranked = sorted(totals.items(), key=lambda item: -item[1])
        rest = sum(value for _, value in ranked[8:])
        rows.append((f"imports, {name}: " + ", ".join(f"{k} {v:.2f}" for k, v in ranked[:8]), sum(totals.values())))
        rows.append((f"  (other packages {rest:.2f})", rest))
    return rows


def breakdown_child(argv: list[str]) -> None:
    """Run ``heliostep`` with ``argv`` in this process, its stages timed; print one line per stage."""
    import importlib

    started = time.perf_counter()
    import heliostep.cli.run  # noqa: F401  (the command's modules: what make_parser imports)

    spent = {"imports of the command's modules": time.perf_counter() - started}

    def timed(label, function):
        @functools.wraps(function)
        def wrapper(*args, **kwargs):
            begun = time.perf_counter()
            try:
                return function(*args, **kwargs)
            finally:
                spent[label] = spent.get(label, 0.0) + time.perf_counter() - begun

        return wrapper

    for label, module_name, attribute in STAGES:
        path = module_name.split(".")
        try:
            owner = importlib.import_module(module_name)
        except ModuleNotFoundError:  # a class: module.Class, or a module this tree does not have
            try:
                owner = getattr(importlib.import_module(".".join(path[:-1])), path[-1])
            except (ModuleNotFoundError, AttributeError):
                continue
        if hasattr(owner, attribute):
            setattr(owner, attribute, timed(label, getattr(owner, attribute)))
    from heliostep.cli import main

    status = main(argv)
    total = time.perf_counter() - started
    for label, seconds in spent.items():
        print(f"{seconds:8.3f} s  {label}")
    print(f"{total - sum(spent.values()):8.3f} s  other (parsing, folder lock, manifest, report)")
    print(f"{total:8.3f} s  in the process after the interpreter's start (exit status {status})")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scenario", nargs="?", type=Path, default=SCENARIO)
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--no-breakdown", action="store_true")
    parser.add_argument(
        "--baseline", type=Path, help="another checkout's src folder: its runs timed side by side (PYTHONPATH)"
    )
    parser.add_argument("--breakdown", nargs=argparse.REMAINDER, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.breakdown is not None:
        breakdown_child(args.breakdown)
        return 0
    with tempfile.TemporaryDirectory(prefix="heliostep-bench-cli-") as folder:
        out = Path(folder)
        # bytecode as a user's second run has it: the warm-up writes it, into a folder of this benchmark's
        os.environ.pop("PYTHONDONTWRITEBYTECODE", None)
        os.environ["PYTHONPYCACHEPREFIX"] = str(out / "bytecode")
        timed = variants(args.scenario, out, args.baseline)
        for command, env in timed.values():  # warm-up: FMUs, kernel, caches; page cache
            run_once(command, env)
        walls: dict[str, list[float]] = {name: [] for name in timed}
        cpus: dict[str, list[float]] = {name: [] for name in timed}
        for _ in range(args.repeat):
            for name, (command, env) in timed.items():
                wall, cpu = run_once(command, env)
                walls[name].append(wall)
                cpus[name].append(cpu)
        median = {name: statistics.median(values) for name, values in walls.items()}
        cpu = {name: statistics.median(values) for name, values in cpus.items()}
        print(f"run: {median['run']:.3f} s, no-plots {median['no-plots']:.3f} s")
        for name, values in walls.items():
            print(
                f"  {name:26s} median {median[name]:.3f} s wall, {cpu[name]:.3f} s CPU  "
                f"({', '.join(f'{v:.2f}' for v in values)})"
            )
        print(
            f"  plots add {median['run'] - median['no-plots']:.3f} s; supervision costs "
            f"{median['no-plots'] - median['no-plots --no-supervise']:.3f} s"
        )
        alone = median["the run's libraries alone"]
        no_pandas = median["the run's libraries but pandas"]
        print(
            f"  the run's libraries imported alone ({LIBRARIES}): {alone:.3f} s, "
            f"{alone / median['no-plots']:.2f} of the no-plots run; without pandas "
            f"{no_pandas:.3f} s: pandas adds {alone - no_pandas:.3f} s to every run"
        )
        if args.baseline is not None:
            print(
                f"  against {args.baseline}: run {median['run'] / median['run, baseline']:.2f}x, "
                f"no-plots {median['no-plots'] / median['no-plots, baseline']:.2f}x of its time"
            )
        print(
            f"  load: {os.getloadavg()[0]:.2f} (1 min), {os.cpu_count()} cores; import pvlib "
            f"{median['import pvlib']:.3f} s here"
        )
        if args.no_breakdown:
            return 0
        for label, plots in (("with plots", []), ("--no-plots", ["--no-plots"])):
            command = [
                sys.executable,
                __file__,
                "--breakdown",
                "run",
                str(args.scenario),
                "--out",
                str(out / f"breakdown{len(plots)}"),
                *plots,
            ]
            started = time.perf_counter()
            done = subprocess.run(command, capture_output=True, text=True)
            wall = time.perf_counter() - started
            lines = [line for line in done.stdout.splitlines() if line.startswith(" ") and " s  " in line]
            print(f"breakdown, {label} (one run, whole process {wall:.3f} s):")
            print("\n".join(f"  {line}" for line in lines))
        for label, seconds in import_breakdown(args.scenario, out):
            print(f"  {seconds:6.2f} s  {label}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
