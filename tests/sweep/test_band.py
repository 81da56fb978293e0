"""Uncertainty bands (``heliostep run --band N``): the ranges file, the Latin-hypercube design, the
samples on a real local Dask cluster (127.0.0.1) with the real FMUs, and the command line.

The cluster's two single-threaded workers have HELIOSTEP_MODELS and HELIOSTEP_FMUS pointing at an
empty folder, so every sample that runs proves the FMUs were shipped to them. The scenario is
jan21-central cut to 30 s (two steps).
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
from pathlib import Path

import numpy as np
import pytest

from heliostep import cli
from heliostep.errors import InputError
from heliostep.paths import scenarios_dir
from heliostep.run import RunOptions, resolve_fmus, run_scenario
from heliostep.scenario import load_scenario
from heliostep.sweep.band import RANGES_FILE, band_design, load_ranges
from heliostep.sweep.band_run import band_record, run_band, run_figures
from heliostep_process import HELIOSTEP
from loopback_cluster import loopback_client

CENTRAL = scenarios_dir() / "jan21-central.yaml"
SHORT = ["window.duration=30", "output.interval=0.5"]
#: Inside the shipped ranges (24-48 V, 23-45 V/A): the middle of each.
INSIDE = ["parameters.motor.V_supply=36", "parameters.motor.K_current=34"]


@pytest.fixture(scope="module")
def client(fmu_paths, tmp_path_factory):
    """A client of a 2-worker local cluster whose workers cannot build or find FMUs themselves."""
    empty = tmp_path_factory.mktemp("no-models")
    env = {"HELIOSTEP_MODELS": str(empty), "HELIOSTEP_FMUS": str(empty)}
    with loopback_client(**env) as dask_client:
        yield dask_client


def _short(*overrides: str):
    return load_scenario(CENTRAL, [*(f"{item}" for item in SHORT), *overrides])


def _ranges_file(folder: Path, text: str) -> Path:
    path = folder / "ranges.yaml"
    path.write_text(text)
    return path


def test_shipped_ranges_carry_the_sourced_driver_ranges():
    """The shipped file gives docs/physics.md's driver ranges and the rotor damping's, each with its
    source; no friction entry (no source gives a range for T_c or M_c)."""
    ranges = {parameter.key: parameter for parameter in load_ranges()}
    assert set(ranges) == {"parameters.motor.V_supply", "parameters.motor.K_current", "parameters.mechanics.B_m"}
    damping = ranges["parameters.mechanics.B_m"]
    assert (damping.low, damping.high, damping.unit) == (0.0, 8e-4, "N.m.s/rad") and "Simscape" in damping.source
    bus, gain = ranges["parameters.motor.V_supply"], ranges["parameters.motor.K_current"]
    assert (bus.low, bus.high, bus.unit) == (24.0, 48.0, "V")
    assert (gain.low, gain.high, gain.unit) == (18.1, 33.9, "V/A")
    assert "Erickson" in gain.source and "TMC5160" in gain.source and "SELV" in bus.source
    # K = 2 pi f_c L for a crossover at a tenth of the TMC5160's 16-30 kHz chopper and L = 1.8 mH (Table 3)
    assert 2 * np.pi * 1.6e3 * 1.8e-3 == pytest.approx(gain.low, abs=0.05)
    assert 2 * np.pi * 3.0e3 * 1.8e-3 == pytest.approx(gain.high, abs=0.05)
    friction = {"parameters.mechanics.T_c", "parameters.mechanics.M_c"}
    assert "T_c" in RANGES_FILE.read_text() and not friction & set(ranges)


@pytest.mark.parametrize("n", [3, 4, 7])
def test_latin_hypercube_puts_one_sample_in_each_stratum(n, fmu_paths):
    """Each of the N equal strata of each key's range holds exactly one sample (computed here from
    the values), every value is inside its range, and the same seed gives the same design."""
    scenario = _short()
    paths = resolve_fmus(scenario)
    design = band_design(scenario, load_ranges(), n, seed=5, fmu_paths=paths)
    assert design.values.shape == (n, 3)
    for column, parameter in enumerate(design.ranges):
        values = design.values[:, column]
        assert np.all((values >= parameter.low) & (values <= parameter.high))
        strata = np.floor((values - parameter.low) / (parameter.high - parameter.low) * n).astype(int)
        assert sorted(strata) == list(range(n)), (parameter.key, values)
    again = band_design(scenario, load_ranges(), n, seed=5, fmu_paths=paths)
    assert np.array_equal(design.values, again.values)
    other = band_design(scenario, load_ranges(), n, seed=6, fmu_paths=paths)
    assert not np.array_equal(design.values, other.values)
    # the nominal values are the FMUs' defaults (the scenario sets none): the paper's 3.1 V and 100 V/A, outside;
    # no rotor damping, the range's bottom, inside
    assert design.nominal == {
        "parameters.motor.V_supply": 3.1,
        "parameters.motor.K_current": 100.0,
        "parameters.mechanics.B_m": 0.0,
    }
    assert [key["nominal_in_range"] for key in design.record()["keys"]] == [False, False, True]


def test_paper_literal_pins_the_papers_bus(fmu_paths):
    """jan21-paper-literal keeps the paper's 3.1 V and its undamped rotor: only the current-loop gain varies."""
    scenario = load_scenario(scenarios_dir() / "jan21-paper-literal.yaml", SHORT)
    design = band_design(scenario, load_ranges(), 3, fmu_paths=resolve_fmus(scenario))
    assert [parameter.key for parameter in design.ranges] == ["parameters.motor.K_current"]
    assert design.pinned == ("parameters.motor.V_supply", "parameters.mechanics.B_m")
    for index in range(3):
        assert design.scenario_of(scenario, index).parameters["motor"].get("V_supply") is None  # the FMU's 3.1 V


def test_band_extremes_bracket_the_nominal_run(client, fmu_paths, tmp_path):
    """One key (the bus voltage, 24-48 V) and N = 3 with the nominal at the range's middle, 36 V: the
    nominal lies in the middle stratum, so one sample is below it and one above. A figure monotone in
    the bus is then bracketed by the band's extremes exactly: peak torque and max tracking error
    grow with it (the faster current rise swings the rotor harder; both checked here on the samples).
    Every other (the settling time too: with the detent torque it moves by under 1e-3 of itself over
    the range)
    figure is bracketed to within 10 x the solver's rtol (1e-6) of its size: those barely depend on
    the bus (a spread below 1e-4 of their value), and the solver does not order them more finely."""
    ranges = _ranges_file(
        tmp_path, "ranges:\n  - {key: parameters.motor.V_supply, low: 24, high: 48, unit: V, source: t}\n"
    )
    scenario = _short(*INSIDE)
    paths = resolve_fmus(scenario)
    design = band_design(scenario, load_ranges(ranges), 3, fmu_paths=paths, ranges_file=ranges)
    strata = np.floor((design.values[:, 0] - 24.0) / 24.0 * 3).astype(int)
    assert design.nominal["parameters.motor.V_supply"] == 36.0 and sorted(strata) == [0, 1, 2]
    nominal = run_figures(run_scenario(scenario, RunOptions(keep_trace=False, fmu_paths=paths)))
    outcome = run_band(scenario, design, paths, client=client)
    record = band_record(nominal, outcome)
    assert record["complete"] and record["failed"] == [] and "note" not in record
    figures = record["figures"]
    for name in ("peak_torque_Nm", "max_tracking_error_deg"):
        entry = figures[name]
        assert entry["min"] < entry["nominal"] < entry["max"], (name, entry)
        # monotone in the bus over the samples and the nominal, so bracketed (either direction)
        by_bus = sorted(
            [(36.0, entry["nominal"])] + [(v, r["figures"][name]) for v, r in zip(design.values[:, 0], outcome.results)]
        )
        steps = np.diff([figure for _, figure in by_bus])
        assert np.all(steps > 0) or np.all(steps < 0), (name, by_bus)
    for name, entry in figures.items():
        if name.startswith("solver."):  # the solver's work: counted, not a smooth function of the bus
            continue
        # relative to the figure's size, and absolute for the figures that are 0 but for the solver's
        # noise (final_lag_steps: a few 1e-8 of a step either side of the detent)
        tolerance = 10 * 1e-6 * (1.0 + max(abs(entry["nominal"]), abs(entry["min"]), abs(entry["max"])))
        assert entry["min"] - tolerance <= entry["nominal"] <= entry["max"] + tolerance, (name, entry)
        assert entry["samples"] == 3
    values = [result["figures"]["peak_torque_Nm"] for result in outcome.results]
    assert figures["peak_torque_Nm"]["median"] == sorted(values)[1]


def test_a_failed_sample_is_reported_never_dropped(client, fmu_paths, tmp_path):
    """The phase inductance over -1.8 to 1.8 mH with N = 2: the Latin hypercube puts one sample in
    each half, so exactly one has L < 0, whose current loop runs away (the run fails); it is listed
    in ``failed`` with its error, named in the note, and the statistics are over the other."""
    ranges = _ranges_file(
        tmp_path, "ranges:\n  - {key: parameters.motor.L, low: -1.8e-3, high: 1.8e-3, unit: H, source: test}\n"
    )
    scenario = _short()
    paths = resolve_fmus(scenario)
    design = band_design(scenario, load_ranges(ranges), 2, fmu_paths=paths, ranges_file=ranges)
    negative = int(np.argmin(design.values[:, 0]))
    assert design.values[negative, 0] < 0 < design.values[1 - negative, 0]
    seen = []
    outcome = run_band(scenario, design, paths, client=client, on_sample=seen.append)
    assert sorted(result["index"] for result in seen) == [0, 1]
    record = band_record(run_figures(run_scenario(scenario, RunOptions(keep_trace=False, fmu_paths=paths))), outcome)
    assert record["failed"] == [negative] and not record["complete"]
    failed = record["sample_results"][negative]
    assert failed["status"] == "failed" and failed["error"] and failed["figures"] is None
    assert f"1 of 2 samples failed (sample(s) {negative}" in record["note"]
    peak = record["figures"]["peak_torque_Nm"]
    good = record["sample_results"][1 - negative]["figures"]["peak_torque_Nm"]
    assert peak["samples"] == 1 and peak["min"] == peak["median"] == peak["max"] == good


def test_cli_band_writes_summary_and_a_sample_equals_a_plain_run(client, fmu_paths, tmp_path):
    """``heliostep run --band 3`` (on the module's cluster, --scheduler): summary.json's band has the design and each
    figure's nominal/min/median/max; stdout prints them; and one sample's figures equal those of a
    plain ``heliostep run --set`` of that sample's values (the band runs what it says)."""
    band_out, plain_out = tmp_path / "band", tmp_path / "plain"
    sets = [arg for item in SHORT for arg in ("--set", item)]
    done = subprocess.run(
        [
            *HELIOSTEP,
            "run",
            str(CENTRAL),
            *sets,
            "--no-plots",
            "--out",
            str(band_out),
            "--band",
            "3",
            "--scheduler",
            client.scheduler.address,
        ],
        capture_output=True,
        text=True,
        timeout=400,
    )
    assert done.returncode == 0, done.stderr
    summary = json.loads((band_out / "summary.json").read_text())
    band = summary["band"]
    assert band["complete"] and band["samples"] == 3 and band["finished"] == [0, 1, 2]
    assert band["design"]["seed"] == 21 and len(band["design"]["values"]) == 3
    peak = band["figures"]["peak_torque_Nm"]
    assert peak["nominal"] == summary["peak_torque_Nm"]
    samples = [result["figures"]["peak_torque_Nm"] for result in band["sample_results"]]
    assert (peak["min"], peak["median"], peak["max"]) == (min(samples), sorted(samples)[1], max(samples))
    # the nominal 3.1 V and 100 V/A are outside the ranges: said, not hidden
    assert "V_supply = 3.1 V lies outside its range 24-48 V" in band["note"]
    line = next(text for text in done.stdout.splitlines() if text.strip().startswith("peak_torque_Nm"))
    assert [float(word) for word in line.split()[1:]] == pytest.approx(
        [peak["nominal"], peak["min"], peak["median"], peak["max"]], rel=1e-4
    )
    chosen = band["sample_results"][1]
    plain = subprocess.run(
        [
            *HELIOSTEP,
            "run",
            str(CENTRAL),
            *sets,
            *[arg for key, value in chosen["values"].items() for arg in ("--set", f"{key}={value!r}")],
            "--no-plots",
            "--out",
            str(plain_out),
        ],
        capture_output=True,
        text=True,
        timeout=200,
    )
    assert plain.returncode == 0, plain.stderr
    alone = json.loads((plain_out / "summary.json").read_text())
    for name in ("peak_torque_Nm", "max_tracking_error_deg", "electrical_energy_J", "rms_tracking_error_deg"):
        assert chosen["figures"][name] == pytest.approx(alone[name], rel=1e-12), name
    assert chosen["figures"]["settling_time_s.max"] == pytest.approx(alone["settling_time_s"]["max"], rel=1e-12)
    assert alone["peak_torque_Nm"] != pytest.approx(summary["peak_torque_Nm"], rel=1e-3)  # not the nominal


@pytest.mark.parametrize(
    "args, ranges, expected",
    [
        (["--band", "1"], None, "--band 1: expected a whole number of samples from 2 to 1000"),
        (["--band", "100000"], None, "--band 100000: expected a whole number"),
        (
            ["--band", "3", "--scheduler", "tcp://127.0.0.1:1"],
            None,
            "cannot reach the Dask scheduler at tcp://127.0.0.1:1",
        ),
        (
            ["--band", "3"],
            "  - {key: sequencer.current, low: -5, high: -1, unit: A, source: s}\n",
            ": band sample 0 (sequencer.current=",
        ),
        (
            ["--band", "3"],
            "  - {key: parameters.motor.R_x, low: 1, high: 2, unit: O, source: s}\n",
            "has no Real parameter 'R_x'",
        ),
        (
            ["--band", "3"],
            "  - {key: parameters.gearbox.b, low: 1, high: 2, unit: O, source: s}\n",
            "no FMU instance 'gearbox'",
        ),
        (
            ["--band", "3"],
            "  - {key: sequencer.nothing, low: 1, high: 2, unit: A, source: s}\n",
            "sequencer.nothing: the scenario",
        ),
        (
            ["--band", "3"],
            "  - {key: parameters.motor.V_supply, high: 2, unit: V, source: s}\n",
            "(parameters.motor.V_supply): missing 'low'",
        ),
        (
            ["--band", "3"],
            "  - {key: parameters.motor.V_supply, low: 24, unit: V, source: s}\n",
            "(parameters.motor.V_supply): missing 'high'",
        ),
        (
            ["--band", "3"],
            "  - {key: parameters.motor.V_supply, low: 48, high: 24, unit: V, source: s}\n",
            "low = 48 is not below high = 24",
        ),
        (["--exact"], None, "--exact: only with --band"),
    ],
)
def test_bad_band_input_is_exit_2_naming_the_key(args, ranges, expected, tmp_path, capsys, fmu_paths):
    """Before anything runs (no output folder made)."""
    extra = []
    if ranges is not None:
        extra = ["--band-ranges", str(_ranges_file(tmp_path, "ranges:\n" + ranges))]
    out = tmp_path / "out"
    sets = [arg for item in SHORT for arg in ("--set", item)]
    status = cli.main(["run", str(CENTRAL), *sets, "--no-plots", "--out", str(out), *args, *extra])
    assert status == 2
    assert expected in capsys.readouterr().err
    assert not out.exists()


def test_pinned_key_not_in_the_ranges_is_an_input_error(tmp_path, fmu_paths):
    scenario = load_scenario(CENTRAL, [*SHORT, "band.pinned=[parameters.motor.L]"])
    with pytest.raises(InputError, match=r"band.pinned: 'parameters.motor.L' is not a key of the ranges file"):
        band_design(scenario, load_ranges(), 3, fmu_paths=resolve_fmus(scenario))


def test_ctrl_c_during_the_band_keeps_the_nominal_run(fmu_paths, tmp_path):
    """Ctrl+C as a terminal sends it (SIGINT to the whole process group: the command, its local
    cluster's two workers and their supervised runs) once a sample has finished (six samples of
    seconds each): exit 130, no traceback (the workers leave the signal to the command; a supervised
    run whose worker closes ends with one line), the nominal run's files kept (summary.json
    complete), the band written as interrupted with the samples that finished named on stderr and
    kept in summary.json."""
    out = tmp_path / "out"
    sets = [arg for item in SHORT for arg in ("--set", item)]
    process = subprocess.Popen(
        [*HELIOSTEP, "run", str(CENTRAL), *sets, "--no-plots", "--out", str(out), "--band", "6", "--workers", "2"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,  # its own process group, as a terminal's foreground job
    )
    seen = []
    for line in process.stderr:  # the first sample finished: the band is running on the cluster
        seen.append(line)
        if "finished (1 of 6)" in line:
            break
    assert process.poll() is None, "".join(seen)
    os.killpg(process.pid, signal.SIGINT)
    stdout, rest = process.communicate(timeout=200)
    stderr = "".join(seen) + rest
    assert process.returncode == 130, stderr
    for text in ("Traceback", "KeyboardInterrupt", "BrokenPipeError"):
        assert text not in stderr, stderr
    summary = json.loads((out / "summary.json").read_text())
    assert summary["complete"] is True and summary["peak_torque_Nm"] > 0
    assert (out / "trace.parquet").is_file()
    band = summary["band"]
    assert band["interrupted"] and not band["complete"]
    finished = band["finished"]
    assert 1 <= len(finished) < 6
    assert f"{len(finished)} of 6 samples finished ({', '.join(map(str, finished))})" in stderr
    for result in band["sample_results"]:
        assert (result["status"] == "ok") == (result["index"] in finished), result
