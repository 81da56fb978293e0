"""``heliostep size`` with step families: a candidate's days composed and certified give the figures the
same days co-simulated in full give (``exact``), within the certificate's tolerances."""

from __future__ import annotations

import dataclasses

from heliostep.paths import scenarios_dir
from heliostep.scenario.catalogue import load_catalogue
from heliostep.sizing.case import CERTIFIED_CASE_FIGURES
from heliostep.sizing.sheet import composition_record
from heliostep.sizing.size import plan_sizing, run_sizing_cases
from heliostep.sweep.certificate import CERTIFIED_FIGURES, row_deviation

SCENARIO = scenarios_dir() / "jan21-central.yaml"
#: Five days of two hours from 10:00, one current: beyond its two certificate days, six hours of window.
DAYS = [20, 80, 140, 200, 260]


def test_a_candidates_days_composed_are_its_days_in_full(fmu_paths):
    (candidate,) = load_catalogue(None, ["QSH8618-156-62-1280"])
    candidate = dataclasses.replace(candidate, currents=(candidate.currents[-1],))
    overrides = ["window.start=10:00", "window.duration=7200"]
    plan = plan_sizing(SCENARIO, [candidate], design_gust=20.0, days=DAYS, overrides=overrides, band_days=False)
    composed = run_sizing_cases(plan, certify=2)  # its one family in a pool process
    exact = run_sizing_cases(plan, exact=True)
    assert composition_record(list(exact.values()))["methods"] == {"full": 5}
    record = composition_record(list(composed.values()))
    assert record["methods"] == {"composed": 3, "certificate": 2}
    for key, full in exact.items():
        assert composed[key]["steps_commanded"] == full["steps_commanded"] > 50
        for name in CERTIFIED_CASE_FIGURES:
            assert row_deviation(full, composed[key], name) <= CERTIFIED_FIGURES[name], (key, name)
        derived = row_deviation(
            {"electrical_energy_J": full["drive_energy_per_day_J"]},
            {"electrical_energy_J": composed[key]["drive_energy_per_day_J"]},
            "electrical_energy_J",
        )
        assert derived <= CERTIFIED_FIGURES["electrical_energy_J"]
    assert set(record["certificate"]) == set(CERTIFIED_CASE_FIGURES)  # the figures a day carries
    for name in CERTIFIED_CASE_FIGURES:
        assert 0.0 <= record["certificate"][name]["max_deviation"] <= CERTIFIED_FIGURES[name]
