"""Step families: a case composed from its drive's single-step transients against the same case
co-simulated in full (the FMUs on CVODE), within the tolerances of a sweep's certificate; the cases a family
cannot compose say why."""

from __future__ import annotations

import functools

import numpy as np
import pytest

from heliostep.drive.inputs import prepare_inputs
from heliostep.paths import scenarios_dir
from heliostep.run import RunOptions, run_scenario
from heliostep.run.step_family import build_family, compose_case, family_key, not_composable
from heliostep.scenario import load_scenario
from heliostep.sweep.certificate import CERTIFIED_FIGURES, row_deviation
from heliostep.sweep.worker import summary_figures

#: Half an hour of the paper's morning: about 60 steps on the full grid's figures, as a sweep's case.
HALF_HOUR = ("window.start=10:00", "window.duration=1800", "output.interval=1.0", "output.step_detail=0")


@functools.cache
def _family(motor: str):
    """The half hour's family of the motor variant ``motor`` (built once for the tests that use it)."""
    return build_family(load_scenario(scenarios_dir() / "jan21-central.yaml", (*HALF_HOUR, f"fmus.motor={motor}")))


def _full(scenario) -> dict:
    """The full run's summary, its settling times as a sweep's table has them (as a family composes them)."""
    summary = run_scenario(scenario, RunOptions(keep_trace=False, light_first_order=False)).summary
    return {**summary, **summary_figures(summary)}


def _assert_within_tolerances(full: dict, composed: dict) -> None:
    for name, tolerance in CERTIFIED_FIGURES.items():
        assert row_deviation(full, composed, name) <= tolerance, (name, full[name], composed[name])


def test_a_motor_variant_builds_its_own_family_and_moves_as_the_full_cosimulation(fmu_paths):
    """StepperMotorIdealCurrent (currents imposed, no chopper) in place of StepperMotor: another family key,
    and its composed figures those of its own full run; the two drives' peak currents differ by more than
    the tolerance, so a family that ignored the variant would fail here."""
    scenarios = {
        name: load_scenario(scenarios_dir() / "jan21-central.yaml", (*HALF_HOUR, f"fmus.motor={name}"))
        for name in ("StepperMotor", "StepperMotorIdealCurrent")
    }
    assert len({family_key(scenario) for scenario in scenarios.values()}) == 2
    full, composed = {}, {}
    for name, scenario in scenarios.items():
        composition = compose_case(scenario, _family(name))
        assert composition.fallback is None
        full[name], composed[name] = _full(scenario), composition.figures
        _assert_within_tolerances(full[name], composed[name])
        assert composed[name]["steps_commanded"] == full[name]["steps_commanded"] > 40
    changes = {
        name: full["StepperMotorIdealCurrent"][name] / full["StepperMotor"][name] - 1
        for name in composed["StepperMotor"]
        if name in ("peak_phase_current_A", "peak_torque_Nm")
    }
    assert max(abs(change) for change in changes.values()) > 0.005
    for name, change in changes.items():
        moved = composed["StepperMotorIdealCurrent"][name] / composed["StepperMotor"][name] - 1
        assert moved == pytest.approx(change, abs=2 * CERTIFIED_FIGURES[name]), name


def test_the_composed_settling_times_are_the_converged_cosimulations(fmu_paths):
    """In the paper's morning a swing of the ring peaks at the settling band: at the scenario's rtol 1e-6 the
    solver decides whether it leaves the band, and the full run's longest settling moves by half the ring's
    period (9 %) from rtol 1e-7 (docs/sweep.md, "Settling"). The composed settling times follow the swings'
    heights: they agree with the full run at rtol 1e-7 within 0.5 %."""
    scenario = load_scenario(scenarios_dir() / "jan21-central.yaml", HALF_HOUR)
    composed = compose_case(scenario, _family("StepperMotor")).figures
    tight = _full(load_scenario(scenarios_dir() / "jan21-central.yaml", (*HALF_HOUR, "solver.rtol=1e-7")))
    for name in ("settling_time_max_s", "settling_time_mean_s"):
        assert composed[name] == pytest.approx(tight[name], rel=5e-3), name
    assert composed["settling_not_settled"] == tight["settling_not_settled"] == 0


def test_a_weak_motor_that_loses_steps_falls_back(fmu_paths):
    """2 A against 110 N.m (jan21-weak-motor.yaml): the full run loses 64 steps (tests/cli/test_fail_on.py);
    the family's transients lose them too, so the case is not composed: it falls back to the full
    co-simulation, saying why."""
    scenario = load_scenario(scenarios_dir() / "jan21-weak-motor.yaml")
    family = build_family(scenario)
    assert family.table["lost"].max() > 0
    composition = compose_case(scenario, family)
    assert composition.figures == {}
    assert "lost" in composition.fallback


def test_a_stow_move_falls_back_its_steps_faster_than_a_steps_ring(fmu_paths):
    """jan21-windy.yaml stows in a gust and returns: the slews step faster than a step's ring dies out, so
    the steps interact, which a family of single steps cannot give; asked directly, the family refuses."""
    scenario = load_scenario(scenarios_dir() / "jan21-windy.yaml")
    family = build_family(scenario)
    composition = compose_case(scenario, family)
    assert composition.figures == {} and "stow moves" in composition.fallback
    gaps = np.diff(prepare_inputs(scenario).schedule.times)
    assert np.sum(gaps < family.table["ring"].max()) > 100  # steps before the longest ring has died out


#: The catalogue's QSH4218-41-10-035 at 1 A, at the worst corner of the driver's ranges (24 V, 18.1 V/A, the
#: rotor damping's top) against a 30 m/s gust's moment, as ``heliostep size --design-gust 30`` co-simulates it.
CREEPING = (
    "parameters.motor.R=4.5",
    "parameters.motor.L=0.0075",
    "parameters.motor.k_e=0.2474873734152916",
    "parameters.motor.N_c=50.0",
    "parameters.motor.T_d=0.025",
    "parameters.mechanics.J_m=5.4e-06",
    "sequencer.current=1.0",
    "window.date=2025-06-21",
    "wind.moment=14.699814445256044",
    "parameters.motor.V_supply=24.0",
    "parameters.motor.K_current=18.1",
    "parameters.mechanics.B_m=0.0008",
)


def test_a_drive_that_creeps_to_its_rest_slower_than_a_familys_window_falls_back(fmu_paths):
    """Near its holding torque this drive's panel still creeps toward its rest seconds after a step: the rest a
    family's 1 s transient ends at is not the one the next step starts from (composed, its tracking error was
    off by up to 47 % in a sizing's certificate). The full run shows the creep: from a second after each step
    to the next, some 16 s later, the panel moves on by over a fifth of a step."""
    scenario = load_scenario(scenarios_dir() / "jan21-central.yaml", CREEPING)
    composition = compose_case(scenario, build_family(scenario))
    assert composition.figures == {} and "creep" in composition.fallback
    full = run_scenario(scenario, RunOptions(light_first_order=False)).to_pandas()
    times = prepare_inputs(scenario).schedule.times
    time, panel = full["time"].to_numpy(), full[scenario.resolved_roles()["panel_angle"]].to_numpy()
    before = panel[np.searchsorted(time, times) - 1]  # just before each step
    step = np.median(np.abs(np.diff(before)))
    after = np.interp(times[:-1] + 1.0, time, panel)  # a second after each step
    assert len(times) > 10 and np.min(np.abs(before[1:] - after)) > 0.2 * step


@pytest.mark.parametrize(
    ("name", "overrides", "why"),
    [
        ("jan21-windy.yaml", (), "wind by its speed"),  # a stow move in a gust: steps faster than the ring
        ("jan21-closed-loop.yaml", (), "tracking.mode closed_loop"),
        ("jan21-central.yaml", ("sequencer.idle_current_fraction=0.5", "sequencer.idle_delay=1"), "idle_current"),
    ],
)
def test_what_a_family_cannot_compose_says_why(name, overrides, why):
    assert why in not_composable(load_scenario(scenarios_dir() / name, overrides))


def test_the_paper_case_is_composable_and_its_key_ignores_the_day_and_the_site():
    base = load_scenario(scenarios_dir() / "jan21-central.yaml")
    assert not_composable(base) is None
    other_day = load_scenario(scenarios_dir() / "jan21-central.yaml", ("window.date=2025-06-21", "site.latitude=37"))
    stronger = load_scenario(scenarios_dir() / "jan21-central.yaml", ("sequencer.current=4",))
    assert family_key(base) == family_key(other_day) != family_key(stronger)
