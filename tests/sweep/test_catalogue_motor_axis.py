"""The sweep axis ``catalogue_motor``: catalogue motors by name, each case the scenario ``heliostep run BASE
--motor NAME`` runs (:func:`heliostep.scenario.catalogue.motor_overrides` on the base), with the other axes'
settings."""

from __future__ import annotations

import pytest
import yaml

from catalogue_entries import QSH8618_65_AT_3A
from heliostep.paths import scenarios_dir
from heliostep.run import run_scenario
from heliostep.scenario import load_scenario
from heliostep.scenario.catalogue import load_catalogue, motor_overrides
from heliostep.sweep import expand_cases, load_sweep, run_sweep
from loopback_cluster import loopback_client
from sweep_checks import PLAIN_FIGURES, assert_refused_before_any_case

BASE = scenarios_dir() / "jan21-central.yaml"
SHORT_WINDOW = ("window.duration=20", "output.interval=0.5")
MOTORS = ["QSH5718-51-28-101", "QSH8618-65-59-340"]


def write_sweep(folder, **content):
    """A sweep file over the paper's scenario with a 20 s window."""
    data = {"base": str(BASE), "overrides": {"window.duration": 20, "output.interval": 0.5}, **content}
    path = folder / "sweep.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def run_items(name: str, catalogue=None, current: float | None = None) -> list[str]:
    """The ``--set`` items of ``heliostep run BASE --motor NAME [--current A]`` with the short window."""
    (candidate,) = load_catalogue(catalogue, [name])
    base = load_scenario(BASE, SHORT_WINDOW)
    current_items = [] if current is None else [f"sequencer.current={current!r}"]
    return [*motor_overrides(base, candidate), *current_items, *SHORT_WINDOW]


@pytest.fixture(scope="module")
def client():
    """A client of a 2-worker loopback cluster."""
    with loopback_client() as dask_client:
        yield dask_client


def test_each_catalogue_motor_sets_what_run_motor_sets(tmp_path):
    spec = load_sweep(write_sweep(tmp_path, axes={"catalogue_motor": MOTORS, "current": [1.5, 2.8]}))
    (axis, _) = spec.axes
    base = load_scenario(BASE, SHORT_WINDOW)
    for candidate in load_catalogue(None, MOTORS):
        settings = axis.overrides(candidate.name, 2024)
        assert [f"{key}={value!r}" for key, value in settings] == list(motor_overrides(base, candidate))
    cases = expand_cases(spec)
    assert [(case.columns["catalogue_motor"], case.columns["current_A"]) for case in cases] == [
        (name, current) for name in MOTORS for current in (1.5, 2.8)
    ]
    for case in cases:
        expected = load_scenario(BASE, run_items(case.columns["catalogue_motor"], current=case.columns["current_A"]))
        assert case.scenario["parameters"] == expected.resolved_dict()["parameters"]
        assert case.scenario["sequencer"] == expected.resolved_dict()["sequencer"]


def test_the_sweep_files_catalogue_is_read_relative_to_it(tmp_path):
    (tmp_path / "mine.yaml").write_text(yaml.safe_dump({"motors": {"big": QSH8618_65_AT_3A}}))
    spec = load_sweep(write_sweep(tmp_path, catalogue="mine.yaml", axes={"catalogue_motor": ["big"]}))
    (case,) = expand_cases(spec)
    expected = load_scenario(BASE, run_items("big", catalogue=tmp_path / "mine.yaml"))
    assert case.columns["catalogue_motor"] == "big"
    assert case.scenario["parameters"] == expected.resolved_dict()["parameters"]


@pytest.mark.parametrize(
    "content, words",
    [
        ({"axes": {"catalogue_motor": ["QSH5718-51"]}}, ["axes.catalogue_motor", "'QSH5718-51'", "QSH5718-51-28-101"]),
        ({"axes": {"catalogue_motor": [57]}}, ["axes.catalogue_motor", "57", "motor catalogue name"]),
        ({"axes": {"current": [2.0]}, "catalogue": "mine.yaml"}, ["catalogue", "catalogue_motor axis"]),
        ({"axes": {"catalogue_motor": ["big"]}, "catalogue": "none.yaml"}, ["axes.catalogue_motor", "none.yaml"]),
    ],
)
def test_a_bad_catalogue_motor_is_refused_naming_the_axis_before_any_case(client, tmp_path, content, words):
    sweep = write_sweep(tmp_path, **content)
    assert_refused_before_any_case(sweep, tmp_path / "results.parquet", client, words)


def test_a_sweep_over_two_catalogue_motors_gives_the_figures_of_run_motor(client, tmp_path):
    sweep = write_sweep(tmp_path, axes={"catalogue_motor": MOTORS, "current": [2.8]})
    outcome = run_sweep(sweep, tmp_path / "results.parquet", client=client)
    assert (outcome.executed, outcome.failed) == (2, 0)
    assert list(outcome.table["catalogue_motor"]) == MOTORS
    for row in outcome.table.itertuples(index=False):
        summary = run_scenario(BASE, overrides=run_items(row.catalogue_motor, current=2.8)).summary
        for key in (*PLAIN_FIGURES, "final_panel_angle_deg"):
            assert getattr(row, key) == summary[key], key
        assert row.settling_time_max_s == summary["settling_time_s"]["max"]
        # the table's k_e-based column follows the catalogue motor: k_e x I
        (candidate,) = load_catalogue(None, [row.catalogue_motor])
        assert row.holding_torque_Nm == pytest.approx(candidate.torque_constant * 2.8, rel=1e-12)
