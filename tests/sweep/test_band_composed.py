"""An uncertainty band's samples composed from their step families on a real two-worker Dask cluster,
certified by samples run both ways: a composed sample against the same sample co-simulated in full (the
band again, its certificate made to fail), figure by figure within the certificate's tolerances."""

from __future__ import annotations

import pytest

from heliostep.cli.band import band_report
from heliostep.paths import scenarios_dir
from heliostep.run import resolve_fmus
from heliostep.scenario import load_scenario
from heliostep.sweep import band_composed
from heliostep.sweep.band import band_design, load_ranges
from heliostep.sweep.band_composed import BAND_CERTIFY, band_ways, certificate_failures
from heliostep.sweep.band_run import band_record, run_band
from heliostep.sweep.certificate import CERTIFIED_FIGURES, row_deviation
from loopback_cluster import loopback_client

CENTRAL = scenarios_dir() / "jan21-central.yaml"
#: 4.1 hours of the paper's day as a sweep case's grid: more window than a family costs (FAMILY_WORTH_S).
LONG = ("window.start=10:00", "window.duration=14760", "output.interval=1.0", "output.step_detail=0")
#: 20 minutes of it, composed here all the same (the threshold set to 0: the method is the same, the cost not).
SHORT = ("window.start=10:00", "window.duration=1200", "output.interval=1.0", "output.step_detail=0")
#: The band's names of the table's settling columns.
SETTLING = {"settling_time_max_s": "settling_time_s.max", "settling_time_mean_s": "settling_time_s.mean"}
SETTLING["settling_not_settled"] = "settling_time_s.not_settled"


def _flat(figures: dict) -> dict:
    return {**figures, **{name: figures.get(band) for name, band in SETTLING.items()}}


@pytest.fixture(scope="module")
def bands(fmu_paths) -> dict:
    """The band of 3 samples composed (2 of them the certificate), and again with a certificate that cannot
    pass (peak torque at tolerance 0), which runs the composed sample in full."""
    scenario = load_scenario(CENTRAL, SHORT)
    paths = resolve_fmus(scenario)
    design = band_design(scenario, load_ranges(), 3, fmu_paths=paths)
    outcomes = {}
    with loopback_client() as client, pytest.MonkeyPatch.context() as patch:
        patch.setattr(band_composed, "FAMILY_WORTH_S", 0.0)
        outcomes["composed"] = run_band(scenario, design, paths, client=client)
        patch.setattr(band_composed, "CERTIFIED_FIGURES", {**CERTIFIED_FIGURES, "peak_torque_Nm": 0.0})
        outcomes["failed"] = run_band(scenario, design, paths, client=client)
    return outcomes


def test_a_bands_samples_are_composed_and_certified(bands):
    outcome = bands["composed"]
    assert outcome.ways.count("certificate") == BAND_CERTIFY and outcome.ways.count("composed") == 1
    record = band_record({"peak_torque_Nm": 1.0}, outcome)
    assert record["complete"] and record["composition"]["methods"] == {"certificate": 2, "composed": 1}
    for name, figure in record["composition"]["certificate"].items():
        assert 0.0 <= figure["max_deviation"] <= figure["tolerance"] == CERTIFIED_FIGURES[name], name
    assert "step families" in record["note"]
    report = band_report(record)
    assert "samples by method: 2 certificate, 1 composed" in report
    assert "certified max deviation peak_torque_Nm" in report
    failed = band_report(band_record({"peak_torque_Nm": 1.0}, bands["failed"]))
    assert "samples by method: 2 certificate, 1 full" in failed
    assert "the certificate failed on peak_torque_Nm: all in full" in failed


def test_a_composed_sample_agrees_with_its_full_cosimulation(bands):
    composed, failed = bands["composed"], bands["failed"]
    assert failed.certificate_failed == ["peak_torque_Nm"]
    (index,) = [i for i, way in enumerate(composed.ways) if way == "composed"]
    assert composed.results[index]["method"] == "composed" and failed.results[index]["method"] == "full"
    full, ours = (_flat(outcome.results[index]["figures"]) for outcome in (failed, composed))
    assert ours["steps_commanded"] == full["steps_commanded"] > 30
    for name, tolerance in CERTIFIED_FIGURES.items():
        assert row_deviation(full, ours, name) <= tolerance, (name, full[name], ours[name])
    for i, way in enumerate(composed.ways):  # the certificate's samples: the same full runs both times
        if way == "certificate":
            assert composed.results[i]["figures"] == failed.results[i]["figures"]


def test_a_band_composes_only_where_a_family_pays(fmu_paths):
    scenario = load_scenario(CENTRAL, LONG)
    design = band_design(scenario, load_ranges(), 5, fmu_paths=resolve_fmus(scenario))
    ways, why = band_ways(load_scenario(CENTRAL, LONG), design)
    assert why is None and ways.count("certificate") == BAND_CERTIFY and ways.count("composed") == 3
    assert band_ways(load_scenario(CENTRAL, LONG), design) == (ways, None)  # drawn by the band's seed
    assert band_ways(load_scenario(CENTRAL, LONG), design, exact=True) == (["full"] * 5, "--exact")
    short, why = band_ways(load_scenario(CENTRAL), design)
    assert short == ["full"] * 5 and "a window of 0.083 h" in why
    closed = load_scenario(scenarios_dir() / "jan21-closed-loop.yaml", ("window.duration=14760",))
    assert "closed_loop" in band_ways(closed, design)[1]


def test_a_certificate_sample_that_failed_or_was_not_composed_fails_the_certificate():
    within = {name: tolerance / 2 for name, tolerance in CERTIFIED_FIGURES.items()}
    assert certificate_failures([within, within]) == []
    assert certificate_failures([within, {**within, "electrical_energy_J": 2e-3}]) == ["electrical_energy_J"]
    assert certificate_failures([within, {**within, "peak_torque_Nm": float("nan")}]) == ["peak_torque_Nm"]
    assert certificate_failures([within, {}]) == list(CERTIFIED_FIGURES) == certificate_failures([])
