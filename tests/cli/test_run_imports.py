"""``heliostep run --no-plots`` imports only what it needs: no matplotlib, no Dask, and, once its sun
grids are in the cache (:mod:`heliostep.solar.sun_cache`), no pvlib; with the same files as pvlib's.

Real processes: the command run twice on a 10-second window of the paper's case, each in a fresh
interpreter that reports the modules it ended with (``sys.modules``), with a sun cache folder of the
test's own: empty for the first run (pvlib computes every grid: the reference), filled for the second
(every grid read back).
"""

from __future__ import annotations

import json
import subprocess
import sys

from heliostep.paths import scenarios_dir

#: Modules a ``--no-plots`` run has no use for (matplotlib: plots; dask/distributed: sweeps and bands; casadi
#: and pymoca: building an FMU, which a run of FMUs already built does not).
NEVER = ("matplotlib", "dask", "distributed", "casadi", "pymoca")
#: Modules only pvlib's computation needs (a run whose sun grids are all cached imports none of them).
#: (urllib.request: pvlib's requests; heliostep's SSP reader, which imports it too, only for a ``system:`` key)
PVLIB_ONLY = ("pvlib", "h5py", "scipy.integrate", "urllib.request")

RUN_AND_REPORT = (
    "import json, pathlib, sys\n"
    "from heliostep.cli import main\n"
    "from heliostep.solar import sun_cache\n"
    "folder = pathlib.Path(sys.argv.pop(1))\n"
    "sun_cache.cache_folder = lambda: folder\n"  # a sun cache of the test's own (the FMUs stay where built)
    "status = main(sys.argv[1:])\n"
    "print(json.dumps({'status': status, 'modules': sorted(sys.modules)}))\n"
)


def run(out, sun_cache) -> tuple[dict, dict]:
    """(what the interpreter reported, summary.json) of one ``heliostep run --no-plots``."""
    args = [
        "run",
        str(scenarios_dir() / "jan21-central.yaml"),
        "--out",
        str(out),
        "--no-plots",
        "--set",
        "window.duration=10",
    ]
    done = subprocess.run([sys.executable, "-c", RUN_AND_REPORT, str(sun_cache), *args], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    report = json.loads(done.stdout.strip().splitlines()[-1])
    summary = json.loads((out / "summary.json").read_text())
    return report, summary


def test_a_no_plots_run_imports_no_plotting_no_dask_and_with_its_sun_cached_no_pvlib(tmp_path):
    sun_cache = tmp_path / "sun-grids"
    reference, reference_summary = run(tmp_path / "pvlib", sun_cache)
    assert "pvlib" in reference["modules"] and len(list(sun_cache.glob("*.npz"))) >= 3  # computed by pvlib itself
    cached, cached_summary = run(tmp_path / "cached", sun_cache)
    for report in (reference, cached):
        assert report["status"] == 0 and not [name for name in NEVER if name in report["modules"]]
    assert not [name for name in PVLIB_ONLY if name in cached["modules"]]
    # the figures and the trace from the cached grids are those from pvlib's, bit for bit
    assert cached_summary == reference_summary
    assert cached_summary["light_energy_J"] > 0.0  # the light on the tube: the sun grid and the clear sky used
    assert (tmp_path / "cached" / "trace.csv").read_bytes() == (tmp_path / "pvlib" / "trace.csv").read_bytes()
