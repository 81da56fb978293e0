"""``heliostep size`` refuses a sizing too large before any simulation: more cases than ``--max-cases`` (a
sweep's ``MAX_CASES`` by default), naming the catalogue entry or ``--days`` that makes them many, and a largest
case over the scenario's memory budget (:func:`heliostep.run.estimate.estimate_run`, no trace kept, as the
cases run). Every refusal is exit 2 with ``--out`` untouched, before any case is built or run."""

from __future__ import annotations

import time
from pathlib import Path

import pytest
import yaml

from catalogue_entries import QSH8618_65_AT_3A
from heliostep.cli import main
from heliostep.paths import scenarios_dir
from heliostep.run import HELD_TRACE_MAX_DURATION
from heliostep.run.estimate import estimate_run
from heliostep.scenario import load_scenario
from heliostep.scenario.catalogue import load_catalogue, motor_overrides
from heliostep.sweep.spec import MAX_CASES

SCENARIO = str(scenarios_dir() / "jan21-central.yaml")
ENTRY = QSH8618_65_AT_3A
#: Refusals come before any case is built: well under this even on a loaded machine [s].
QUICK = 5.0


def _catalogue(folder: Path, motors: dict) -> Path:
    path = folder / "motors.yaml"
    path.write_text(yaml.safe_dump({"motors": motors}), encoding="utf-8")
    return path


def _size(tmp_path: Path, catalogue: Path, *options: str) -> tuple[int, float]:
    argv = ["size", SCENARIO, "--catalogue", str(catalogue), "--set", "window.duration=60", "--design-gust", "30"]
    argv += options
    started = time.perf_counter()
    status = main([*argv, "--out", str(tmp_path / "out")])
    return status, time.perf_counter() - started


def test_an_entry_with_thousands_of_currents_is_refused_naming_it_and_the_count(tmp_path, capsys):
    many = {**ENTRY, "currents": [round(0.001 * (k + 1), 3) for k in range(2000)]}
    catalogue = _catalogue(tmp_path, {"small": ENTRY, "wide": many})
    status, took = _size(tmp_path, catalogue, "--days", "21", "22", "23")
    message = capsys.readouterr().err
    assert status == 2 and took < QUICK
    # (1 + 2000 currents) x 3 days x 2 (the days again at the worst corner)
    assert f"{catalogue}: motors.wide.currents (2,000 currents) makes the sizing too large" in message
    assert "make 12,006 cases" in message and f"over --max-cases = {MAX_CASES:,}" in message
    assert not (tmp_path / "out").exists()


def test_every_day_of_the_year_is_refused_naming_days(tmp_path, capsys):
    catalogue = _catalogue(tmp_path, {"small": {**ENTRY, "currents": [2.0, 3.0, 4.0]}})
    status, took = _size(tmp_path, catalogue, "--days", "all", "--max-cases", "2000")
    message = capsys.readouterr().err
    assert status == 2 and took < QUICK
    assert f"{catalogue}: --days (365 days) makes the sizing too large" in message
    assert "make 2,190 cases, over --max-cases = 2,000" in message  # 3 currents x 365 days x 2
    assert not (tmp_path / "out").exists()


def test_max_cases_counts_the_worst_corners_days_unless_no_band_days(tmp_path, capsys):
    catalogue = _catalogue(tmp_path, {"small": ENTRY})
    status, _ = _size(tmp_path, catalogue, "--days", "21", "22", "--max-cases", "3")
    message = capsys.readouterr().err
    assert status == 2 and "1 current(s) of 1 candidate(s) x 2 days x 2 (each day again at the worst corner" in message
    assert "make 4 cases, over --max-cases = 3" in message
    status, _ = _size(tmp_path, catalogue, "--days", "21", "22", "--max-cases", "1", "--no-band-days")
    message = capsys.readouterr().err
    assert status == 2 and "x 2 days make 2 cases, over --max-cases = 1" in message


@pytest.mark.parametrize("value", ["0", "-3", "2.5", "many"])
def test_a_max_cases_not_a_whole_number_from_one_is_exit_2(tmp_path, capsys, value):
    catalogue = _catalogue(tmp_path, {"small": ENTRY})
    with pytest.raises(SystemExit) as exited:
        _size(tmp_path, catalogue, "--max-cases", value)
    assert exited.value.code == 2
    assert f"--max-cases: {value}: expected a whole number of cases >= 1" in capsys.readouterr().err


def test_the_largest_case_over_the_memory_budget_is_refused_naming_it(tmp_path, capsys):
    """Two candidates, the half-step-angle one commanding twice the steps: a budget between their estimates
    refuses the sizing, naming that candidate's case."""
    fine = {**ENTRY, "step_angle": 0.9}
    catalogue = _catalogue(tmp_path, {"coarse": ENTRY, "fine": fine})
    base = load_scenario(SCENARIO, ["window.duration=60", "output.step_interval=1e-6"])
    memory = {}
    for candidate in load_catalogue(catalogue):
        case = load_scenario(
            SCENARIO, ["window.duration=60", "output.step_interval=1e-6", *motor_overrides(base, candidate)]
        )
        memory[candidate.name] = estimate_run(case, HELD_TRACE_MAX_DURATION, keep_trace=False).memory_bytes
    assert memory["fine"] > memory["coarse"]
    budget = (memory["fine"] + memory["coarse"]) / 2 / 1e9
    options = ["--set", "output.step_interval=1e-6", "--set", f"budget.memory_gb={budget!r}", "--days", "21"]
    status, took = _size(tmp_path, catalogue, *options)
    message = capsys.readouterr().err
    assert status == 2 and took < QUICK
    assert "the largest case, fine@3A/day21:" in message and "over the memory budget" in message
    assert "budget.memory_gb" in message
    assert not (tmp_path / "out").exists()
