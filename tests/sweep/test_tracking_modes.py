"""``tracking.mode`` as a sweep axis: each mode a case on a real Dask cluster (loopback), its row the figures
of the same run in this process, and the loops removing a clock offset that open loop keeps."""

from __future__ import annotations

import pytest

from heliostep.paths import scenarios_dir
from heliostep.run import RunOptions, run_scenario
from heliostep.sweep import load_sweep, read_results, run_sweep
from heliostep.sweep.worker import summary_figures
from loopback_cluster import loopback_client

MODES = ("open_loop", "closed_loop", "hybrid")
OVERRIDES = {
    "window.duration": 60,
    "output.step_detail": 0,
    "faults.clock_offset": 120,
    "tracking.noise_std": 0,
    "tracking.sample_period": 2,
    "tracking.dead_band": 0.005,
}


def test_the_tracking_modes_sweep_as_cases_equal_to_their_runs(tmp_path, fmu_paths):
    sweep = tmp_path / "modes.yaml"
    lines = [f"base: {scenarios_dir() / 'jan21-central.yaml'}", f"axes: {{tracking.mode: [{', '.join(MODES)}]}}"]
    lines += ["overrides:", *(f"  {key}: {value}" for key, value in OVERRIDES.items())]
    sweep.write_text("\n".join(lines) + "\n")
    with loopback_client() as client:
        outcome = run_sweep(load_sweep(sweep), tmp_path / "results.parquet", client=client)
    assert outcome.failed == 0
    rows = read_results(tmp_path / "results.parquet").set_index("tracking.mode")
    errors = {}
    for mode in MODES:
        settings = (*(f"{k}={v}" for k, v in OVERRIDES.items()), f"tracking.mode={mode}")
        here = run_scenario("jan21-central", RunOptions(keep_trace=False, light_first_order=False), overrides=settings)
        for key, value in summary_figures(here.summary).items():
            if isinstance(value, float):
                assert rows.loc[mode, key] == pytest.approx(value, rel=1e-12, abs=0.0), (mode, key)
        errors[mode] = rows.loc[mode, "rms_tracking_error_deg"]
    assert errors["closed_loop"] < errors["open_loop"] / 3 and errors["hybrid"] < errors["open_loop"] / 3
