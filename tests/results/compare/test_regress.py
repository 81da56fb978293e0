"""heliostep.results.compare.regress: the shipped scenarios against their reference traces (the CI regression)."""

import shutil
from pathlib import Path

import junitparser
import pytest

from heliostep.cli import main
from heliostep.paths import scenarios_dir
from heliostep.results.compare.regress import reference_path, shipped_scenarios


def test_every_shipped_scenario_matches_its_reference(fmu_paths, capsys):
    scenarios = shipped_scenarios()
    assert {p.stem for p in scenarios} >= {
        "jan21-central",
        "jan21-day",
        "jan21-ideal-current",
        "jan21-small-angle",
        "jan21-weak-motor",
        "jan21-48v",
        "jan21-windy",
    }
    status = main(["regress"])
    out = capsys.readouterr().out
    assert status == 0, out
    assert out.count(": PASS") == len(scenarios)


@pytest.fixture
def short_scenario(tmp_path):
    """A 20-second copy of the paper's case with its own reference written by --update."""
    text = (scenarios_dir() / "jan21-central.yaml").read_text().replace("duration: 300", "duration: 20")
    scenario = tmp_path / "short.yaml"
    scenario.write_text(text)
    return scenario


def test_update_writes_a_reference_that_then_passes(short_scenario, fmu_paths, capsys):
    assert main(["regress", "--update", str(short_scenario)]) == 0
    assert "reference written (short.reference.parquet)" in capsys.readouterr().out
    assert reference_path(short_scenario).exists()
    assert main(["regress", str(short_scenario)]) == 0
    assert ": PASS" in capsys.readouterr().out


def test_a_model_change_fails_and_names_the_signal(short_scenario, fmu_paths, tmp_path, capsys):
    assert main(["regress", "--update", str(short_scenario)]) == 0
    # the same scenario with a softer damping: the steps ring, the torque changes
    changed = tmp_path / "changed.yaml"
    changed.write_text(short_scenario.read_text() + "parameters: {mechanics: {b: 2000.0}}\n")
    shutil.copy(reference_path(short_scenario), reference_path(changed))
    capsys.readouterr()
    assert main(["regress", str(changed), "--report", str(tmp_path / "report")]) == 1
    out = capsys.readouterr().out
    assert "changed.yaml: FAIL" in out and "motor.tau" in out
    assert (tmp_path / "report" / "changed" / "index.md").exists()
    # --update says what changed, then passes
    assert main(["regress", "--update", str(changed)]) == 0
    assert "CHANGED" in capsys.readouterr().out
    assert main(["regress", str(changed)]) == 0


def test_missing_reference_is_bad_input(short_scenario, capsys):
    assert main(["regress", str(short_scenario)]) == 2
    assert "no reference trace short.reference.parquet" in capsys.readouterr().err


def test_junit_has_a_suite_per_scenario_and_a_case_per_signal(short_scenario, fmu_paths, tmp_path, capsys):
    assert main(["regress", "--update", str(short_scenario)]) == 0
    changed = tmp_path / "changed.yaml"
    changed.write_text(short_scenario.read_text() + "parameters: {mechanics: {b: 2000.0}}\n")
    shutil.copy(reference_path(short_scenario), reference_path(changed))
    junit = tmp_path / "regress.xml"
    assert main(["regress", str(short_scenario), str(changed), "--junit", str(junit)]) == 1
    out = capsys.readouterr().out
    suites = {suite.name: suite for suite in junitparser.JUnitXml.fromfile(str(junit))}
    assert set(suites) == {"short", "changed"}
    # the reference keeps 7 signals (rotor, panel, error, command, torque, two currents)
    assert (suites["short"].tests, suites["short"].failures) == (7, 0)
    failed = {case.name for case in suites["changed"] if case.result}
    assert suites["changed"].tests == 7 and suites["changed"].failures == len(failed) >= 1
    assert "motor.tau" in failed and all(f"{name}" in out for name in failed)
    (failure,) = next(case for case in suites["changed"] if case.name == "motor.tau").result
    assert "outside the tube by" in failure.message and "tube half-width there" in failure.message
    # valid against Apache Ant's JUnit schema (tests/data/junit), the suites numbered, the command their package
    from lxml import etree

    schema = etree.XMLSchema(etree.parse(str(Path(__file__).parents[2] / "data" / "junit" / "ant-junit.xsd")))
    document = etree.parse(str(junit))
    assert schema.validate(document), schema.error_log
    numbered = [(suite.get("id"), suite.get("package")) for suite in document.getroot()]
    assert numbered == [("0", "heliostep regress"), ("1", "heliostep regress")]


def test_an_unusable_junit_path_is_refused_before_any_run(short_scenario, tmp_path, capsys):
    assert main(["regress", str(short_scenario), "--junit", str(tmp_path)]) == 2
    assert "is a folder" in capsys.readouterr().err
