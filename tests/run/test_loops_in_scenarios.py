"""Algebraic loops in a scenario: a loop of two extra FMUs beside the paper's drive (jan21-central), solved
with the scenario's ``solver.loop_rtol`` and ``solver.loop_atol``. A singular loop, found at its first solve
(initialization, before any row), is bad input, exit 2, through ``run_scenario``, the command line
(supervised or not) and a sweep case alike; a loop Newton cannot solve is a run failure, exit 1, naming the
loop's torn input, its value and residual, and the time."""

from __future__ import annotations

import dataclasses
import hashlib
import json
from pathlib import Path

import pytest
import yaml

from heliostep.cli import main
from heliostep.cosim import SolverOptions
from heliostep.errors import InputError
from heliostep.paths import scenarios_dir
from heliostep.run import RunFailed, run_scenario
from heliostep.scenario import SolverConfig
from heliostep.sweep import FmuPayload, expand_cases, load_sweep, run_case
from third_party_fmu import build_mini_fmu

CENTRAL = scenarios_dir() / "jan21-central.yaml"
DRIVE = "[motor.tau, mechanics.tau], [mechanics.theta, motor.theta], [mechanics.omega, motor.omega]"
SINGULAR = "algebraic loop through lag.u at t = 0 s: singular Jacobian (the loop has no unique solution)"


@pytest.fixture(scope="module")
def mini(tmp_path_factory):
    out = tmp_path_factory.mktemp("loop-fmus")
    return {name: build_mini_fmu(name, out) for name in ("Lag", "Gain")}


def lag_loop(mini, k: float, b: float) -> list[str]:
    """A Lag and a Gain in a loop beside the drive, torn at lag.u (u = k (u - y) + b: u = (b - k y) / (1 - k),
    lag.y -> b; k = 1 leaves u undetermined: a singular loop)."""
    return [
        "window.duration=20",
        f"fmus.lag={mini['Lag']}",
        f"fmus.g={mini['Gain']}",
        f"parameters.g.k={k}",
        f"parameters.g.b={b}",
        f"connections=[{DRIVE}, [g.y, lag.u], [lag.e, g.u]]",
    ]


def cli_sets(overrides: list[str]) -> list[str]:
    return [argument for override in overrides for argument in ("--set", override)]


def test_the_loop_tolerance_keys_default_to_the_solvers_own():
    assert (SolverConfig().loop_rtol, SolverConfig().loop_atol) == (SolverOptions.loop_rtol, SolverOptions.loop_atol)
    assert (SolverOptions.loop_rtol, SolverOptions.loop_atol) == (1e-10, 1e-12)


@pytest.mark.parametrize(
    ("override", "words"),
    [("solver.loop_atol=0", "solver.loop_atol"), ("solver.loop_rtol=-1e-9", "solver.loop_rtol")],
)
def test_a_loop_tolerance_out_of_range_is_exit_2_naming_the_key(tmp_path, capsys, override, words):
    assert main(["run", str(CENTRAL), "--no-plots", "--out", str(tmp_path / "out"), "--set", override]) == 2
    assert words in capsys.readouterr().err and not (tmp_path / "out").exists()


def test_a_singular_loop_is_bad_input_through_run_scenario_and_the_command_line(mini, tmp_path, capsys):
    with pytest.raises(InputError) as failure:
        run_scenario(CENTRAL, overrides=lag_loop(mini, 1.0, 0.0))
    assert not isinstance(failure.value, RunFailed)
    assert str(failure.value) == f"{CENTRAL}: {SINGULAR}"
    for supervise in ("--supervise", "--no-supervise"):
        out = tmp_path / supervise
        args = ["run", str(CENTRAL), "--no-plots", supervise, "--out", str(out), *cli_sets(lag_loop(mini, 1.0, 0.0))]
        assert main(args) == 2
        assert capsys.readouterr().err.strip() == f"heliostep run: error: {CENTRAL}: {SINGULAR}"
        assert not out.exists()  # refused before any result


def test_a_singular_loop_is_bad_input_in_a_sweep_case_too(mini, tmp_path, fmu_paths):
    """A sweep over the Gain's k: k = 0.5 runs, k = 1 is the singular loop; its case fails as an InputError."""
    base = tmp_path / "loop.yaml"
    data = yaml.safe_load(CENTRAL.read_text())
    data.update(name="loop", fmus={**data["fmus"], "lag": str(mini["Lag"]), "g": str(mini["Gain"])})
    data["connections"] = yaml.safe_load(f"[{DRIVE}, [g.y, lag.u], [lag.e, g.u]]")
    data["parameters"] = {"g": {"b": 0.0}}
    base.write_text(yaml.safe_dump(data, sort_keys=False))
    sweep = tmp_path / "sweep.yaml"
    sweep.write_text(
        "name: loop-sweep\nbase: loop.yaml\ncombine: product\naxes:\n  parameters.g.k: [0.5, 1.0]\n"
        "overrides:\n  window.duration: 20\n  output.interval: 0.5\n"
    )
    paths = {**fmu_paths, **{str(path): path for path in mini.values()}}  # a case's FMU references: their files
    payloads, rows = {}, {}
    for case in expand_cases(load_sweep(sweep)):
        shas = {}
        for instance, reference in case.scenario["fmus"].items():
            blob = Path(paths[reference]).read_bytes()
            shas[instance] = sha = hashlib.sha256(blob).hexdigest()
            payloads[sha] = FmuPayload(name=f"{instance}.fmu", sha256=sha, data=blob)
        row = run_case(dataclasses.replace(case, fmu_sha256=shas), payloads)
        rows[case.columns["parameters.g.k"]] = row
    assert rows[0.5]["status"] == "ok" and rows[1.0]["status"] == "failed"
    assert rows[1.0]["error_type"] == "InputError" and SINGULAR in rows[1.0]["error"]


def test_a_loop_without_a_real_solution_is_a_run_failure_naming_it(mini, tmp_path, capsys):
    """u = u^2 + 1 (a quadratic Gain, a = 1, fed back through a linear one, k = 1, b = 1): exit 1, the
    trace so far written."""
    out = tmp_path / "out"
    overrides = [
        "window.duration=20",
        f"fmus.sq={mini['Gain']}",
        f"fmus.g={mini['Gain']}",
        "parameters.sq.a=1.0",
        "parameters.sq.k=0.0",
        "parameters.sq.b=0.0",
        "parameters.g.k=1.0",
        "parameters.g.b=1.0",
        f"connections=[{DRIVE}, [g.y, sq.u], [sq.y, g.u]]",
    ]
    assert main(["run", str(CENTRAL), "--no-plots", "--out", str(out), *cli_sets(overrides)]) == 1
    err = capsys.readouterr().err
    assert (
        "heliostep run: error: simulation failed at t = 0 s: algebraic loop through sq.u at t = 0 s: "
        "no convergence in 50 Newton iterations, residual "
    ) in err
    summary = json.loads((out / "summary.json").read_text())
    assert summary["complete"] is False and summary["reason"] == "failed"


def test_the_scenarios_loop_tolerances_reach_the_loop_solver(mini):
    """The loop at 1e9 (b = 1e9, k = 0.5: lag.u from 2e9 down to 1e9): solved with the default relative
    tolerance; with loop_rtol = 0 the absolute 1e-12 is below rounding of the values, a run failure naming
    the tolerance; with loop_rtol = 0 and loop_atol = 1e-3 above it, solved again."""
    loop = lag_loop(mini, 0.5, 1e9)
    result = run_scenario(CENTRAL, overrides=loop)
    statistics = result.metadata["statistics"]
    assert statistics["algebraic_loops"] == ["g.y -> lag.u -> lag.e -> g.u (torn at lag.u)"]
    assert statistics["loop_solves_compiled"] > 0
    # at their defaults the keys are left out of the resolved scenario (its sweep case ids stay as they were)
    assert not {"loop_rtol", "loop_atol"} & set(result.metadata["scenario"]["solver"])
    given = run_scenario(CENTRAL, overrides=[*loop, "solver.loop_rtol=1e-9"])
    assert given.metadata["scenario"]["solver"]["loop_rtol"] == 1e-9
    with pytest.raises(RunFailed, match=r"algebraic loop through lag\.u at t = \S+ s: no convergence") as failure:
        run_scenario(CENTRAL, overrides=[*loop, "solver.loop_rtol=0"])
    assert str(failure.value).endswith("= 1e-12 + 0 |value|)")
    loose = run_scenario(CENTRAL, overrides=[*loop, "solver.loop_rtol=0", "solver.loop_atol=1e-3"])
    assert loose.complete and loose.metadata["statistics"]["loop_solves_compiled"] > 0
