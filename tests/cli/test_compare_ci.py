"""``heliostep compare`` as CI uses it: a vendor's trace against the shipped reference (signals matched
by role, by --map, by a mapping file), verdicts as JUnit XML and GitHub annotations, and the input
refused before comparing (issue 22, item 9: a tolerance for a signal in neither trace, an unusable
--report or --junit folder)."""

from __future__ import annotations

import os
import subprocess
import xml.etree.ElementTree as ET
from pathlib import Path

import junitparser
import numpy as np

from heliostep.cli import main
from heliostep.paths import scenarios_dir
from heliostep.results.trace.files import read_trace, write_trace

REFERENCE = scenarios_dir() / "jan21-central.reference.parquet"
TOLERANCES = scenarios_dir() / "regress-tolerances.yaml"
#: heliostep's column -> the vendor's name for it (the FMU columns, each with a role)
VENDOR = {
    "mechanics.theta": "Drive.rotor.phi",
    "mechanics.theta_p": "Drive.panel.phi",
    "motor.tau": "Drive.motor.tauElectrical",
    "motor.i_a": "Drive.motor.iPhaseA",
    "motor.i_b": "Drive.motor.iPhaseB",
}
#: the absolute tolerance of each renamed signal in scenarios/regress-tolerances.yaml
ABS_TOL = {"mechanics.theta": 1e-4, "mechanics.theta_p": 5e-7, "motor.tau": 1e-2, "motor.i_a": 1e-2, "motor.i_b": 1e-2}


def run(capsys, *args) -> tuple[int, str, str]:
    status = main(["compare", *map(str, args)])
    out, err = capsys.readouterr()
    return status, out, err


def vendor_trace(path, *, roles=True, bump=0.0, noise=True):
    """The shipped reference as a vendor's tool would write it: its FMU signals renamed, its roles
    kept (``role.<role>: <vendor name>``), noise of 0.3 of each tube's absolute half-width on each
    renamed signal (inside the tube), and optionally a torque bump of *bump* N.m for 40 ms at 150 s."""
    frame, meta = read_trace(REFERENCE)
    rng = np.random.default_rng(25)
    for column, tol in ABS_TOL.items():
        if noise:
            frame[column] = frame[column] + rng.uniform(-0.3, 0.3, len(frame)) * tol
    time = frame["time"].to_numpy()
    frame["motor.tau"] = frame["motor.tau"] + np.where((time >= 150.0) & (time <= 150.04), bump, 0.0)
    frame = frame.rename(columns=VENDOR)
    out = {k: v for k, v in meta.items() if not k.startswith(("role.", "unit."))}
    if roles:
        out.update({k: VENDOR.get(v, v) for k, v in meta.items() if k.startswith("role.")})
    out.update({f"unit.{VENDOR.get(k[5:], k[5:])}": v for k, v in meta.items() if k.startswith("unit.")})
    write_trace(frame, path, out)
    return path


def test_vendor_named_trace_passes_by_roles_and_the_output_says_which_matched_which(tmp_path, capsys):
    vendor = vendor_trace(tmp_path / "vendor.parquet")
    status, out, err = run(capsys, vendor, REFERENCE, "--tolerances", TOLERANCES)
    assert status == 0, out + err
    assert "PASS: all 7 signal(s)" in out
    assert "matched: Drive.motor.tauElectrical -> motor.tau (by role torque)" in out
    assert "matched: Drive.panel.phi -> mechanics.theta_p (by role panel_angle)" in out
    assert "matched: panel_angle_error -> panel_angle_error (by name)" in out


def test_vendor_named_trace_fails_under_a_40_ms_torque_bump(tmp_path, capsys):
    # 0.05 N.m for 40 ms: five times the torque's absolute tolerance (1e-2 N.m; rel 1e-3 of < 2 N.m)
    vendor = vendor_trace(tmp_path / "vendor.parquet", bump=0.05)
    junit = tmp_path / "verdicts.xml"
    status, out, _ = run(capsys, vendor, REFERENCE, "--tolerances", TOLERANCES, "--junit", junit)
    assert status == 1
    assert "FAIL: 1 of 7 signal(s) outside tolerance: motor.tau" in out
    row = next(line for line in out.splitlines() if line.startswith("motor.tau "))
    assert row.split()[-1] == "N.m" and 150.0 <= float(row.split()[3]) <= 150.04
    failure = junitparser.JUnitXml.fromfile(str(junit))
    (suite,) = list(failure)
    cases = {case.name: case for case in suite}
    (result,) = cases["motor.tau"].result
    # the message: 0.05 N.m over a tube of about 1e-2 N.m half-width (the noise moves it by < 3e-3)
    assert "outside the tube by" in result.message and "at t = 150" in result.message
    excess = float(result.message.split("outside the tube by ")[1].split()[0])
    half_width = float(result.message.split("tube half-width there ")[1].split()[0])
    assert 0.05 - 1e-2 - 4e-3 < excess < 0.05 - 1e-2 + 4e-3
    assert 1e-2 <= half_width < 1.3e-2


def test_names_that_differ_without_roles_are_bad_input_and_map_options_or_a_map_file_match_them(tmp_path, capsys):
    vendor = vendor_trace(tmp_path / "vendor.csv", roles=False)
    status, _, err = run(capsys, vendor, REFERENCE, "--tolerances", TOLERANCES)
    assert status == 2 and "no column matches the signal(s) 'mechanics.theta'" in err
    maps = [f"--map={v}={k}" for k, v in VENDOR.items()]
    status, out, err = run(capsys, vendor, REFERENCE, "--tolerances", TOLERANCES, *maps)
    assert status == 0, err
    assert "matched: Drive.motor.iPhaseB -> motor.i_b (by explicit)" in out
    (tmp_path / "map.yaml").write_text("".join(f"{v}: {k}\n" for k, v in VENDOR.items()))
    (tmp_path / "map.csv").write_text("reference,actual\n" + "".join(f"{k},{v}\n" for k, v in VENDOR.items()))
    for mapping in ("map.yaml", "map.csv"):
        status, out, err = run(capsys, vendor, REFERENCE, "--tolerances", TOLERANCES, "--map-file", tmp_path / mapping)
        assert status == 0, err
        assert "matched: Drive.rotor.phi -> mechanics.theta (by explicit)" in out
    status, _, err = run(capsys, vendor, REFERENCE, "--map", "Drive.nothing=motor.tau")
    assert status == 2 and "has no column 'Drive.nothing'" in err
    status, _, err = run(capsys, vendor, REFERENCE, "--map", "motor.tau")
    assert status == 2 and "expected ACTUAL=REFERENCE" in err


def test_junit_has_one_test_case_per_signal_with_the_counts_and_the_structure_of_the_ant_schema(tmp_path, capsys):
    vendor = vendor_trace(tmp_path / "vendor.parquet", bump=0.05)
    # a second failure: the currents' tolerance tightened far below the noise
    tight = tmp_path / "tight.yaml"
    tight.write_text(
        TOLERANCES.read_text().replace("motor.i_b: {abs: 1.0e-2, rel: 1.0e-3}", "motor.i_b: {abs: 1.0e-9}")
    )
    junit = tmp_path / "verdicts.xml"
    assert run(capsys, vendor, REFERENCE, "--tolerances", tight, "--junit", junit)[0] == 1
    # reader 1: junitparser (PyPI), as CI plug-ins read it
    xml = junitparser.JUnitXml.fromfile(str(junit))
    (suite,) = list(xml)
    assert (suite.tests, suite.failures, suite.errors) == (7, 2, 0)
    failed = sorted(case.name for case in suite if case.result)
    assert failed == ["motor.i_b", "motor.tau"]
    assert all(case.classname == "compare" for case in suite)
    # reader 2: lxml (fmpy's XML library), validating against Apache Ant's JUnit schema as tests/data/junit has it
    from lxml import etree

    schema = etree.XMLSchema(etree.parse(str(Path(__file__).parents[1] / "data" / "junit" / "ant-junit.xsd")))
    document = etree.parse(str(junit))
    assert schema.validate(document), schema.error_log
    root = ET.parse(junit).getroot()
    assert root.tag == "testsuites" and not root.attrib  # the schema allows the wrapper no attribute
    (element,) = root
    assert (element.get("package"), element.get("id"), element.get("failures")) == ("heliostep", "0", "2")
    children = [child.tag for child in element]
    assert children == ["properties"] + ["testcase"] * 7 + ["system-out", "system-err"]
    for case in element.iter("testcase"):
        assert {"name", "classname", "time"} <= set(case.attrib)
        for failure in case:
            assert failure.tag == "failure" and {"message", "type"} <= set(failure.attrib)


def test_github_annotations_when_github_actions_is_true_or_asked(tmp_path, capsys, monkeypatch):
    vendor = vendor_trace(tmp_path / "vendor.parquet", bump=0.05)
    monkeypatch.delenv("GITHUB_ACTIONS", raising=False)
    assert "::error" not in run(capsys, vendor, REFERENCE, "--tolerances", TOLERANCES)[1]
    monkeypatch.setenv("GITHUB_ACTIONS", "true")
    out = run(capsys, vendor, REFERENCE, "--tolerances", TOLERANCES)[1]
    (line,) = [line for line in out.splitlines() if line.startswith("::error ")]
    # properties escaped as GitHub's workflow commands want (':' -> %3A, ',' -> %2C)
    # the file by its path from the repository's root (the git top level of the current folder), as GitHub
    # attaches an annotation
    top = Path(subprocess.run(["git", "rev-parse", "--show-toplevel"], capture_output=True, text=True).stdout.strip())
    shown = REFERENCE.resolve().relative_to(top.resolve()).as_posix() if top.name else str(REFERENCE)
    assert line.startswith(f"::error file={shown},title=compare%3A motor.tau outside its tolerance tube::")
    assert "outside the tube by" in line
    assert "::error" not in run(capsys, vendor, REFERENCE, "--tolerances", TOLERANCES, "--annotations", "none")[1]
    monkeypatch.delenv("GITHUB_ACTIONS")
    assert "::error file=" in run(capsys, vendor, REFERENCE, "--tolerances", TOLERANCES, "--annotations", "github")[1]
    # a given root: a file under it by its path from it, one outside as given
    github = ("--tolerances", TOLERANCES, "--annotations", "github", "--annotations-root")
    for root, shown in ((REFERENCE.parents[1], "scenarios/jan21-central.reference.parquet"), (tmp_path, REFERENCE)):
        assert f"::error file={shown},title=" in run(capsys, vendor, REFERENCE, *github, root)[1]


# --------------------------------------------------------------------------- refused before comparing (#22, 9)


def test_a_tolerance_for_a_signal_in_neither_trace_is_bad_input(tmp_path, capsys):
    vendor = vendor_trace(tmp_path / "vendor.parquet", bump=0.05)
    # the typo 'motor.tua' would have left motor.tau at the default tolerance: now refused
    typo = tmp_path / "typo.yaml"
    typo.write_text("signals:\n  motor.tua: {abs: 1.0}\n")
    status, out, err = run(capsys, vendor, REFERENCE, "--tolerances", typo)
    assert status == 2 and "motor.tua" in err and "neither trace" in err and out == ""
    # an entry naming the actual's (vendor) column of a matched signal applies to it
    loose = tmp_path / "loose.yaml"
    loose.write_text(
        TOLERANCES.read_text().replace(
            "motor.tau: {abs: 1.0e-2, rel: 1.0e-3}", "Drive.motor.tauElectrical: {abs: 0.1, rel: 1.0e-3}"
        )
    )
    assert run(capsys, vendor, REFERENCE, "--tolerances", loose)[0] == 0


def test_a_read_only_report_folder_is_bad_input_before_comparing(tmp_path, capsys):
    folder = tmp_path / "ro"
    folder.mkdir()
    folder.chmod(0o500)
    # root writes into a folder of mode 0o500; the kernel's /proc/sys refuses new entries even to root
    target = folder if os.geteuid() != 0 else Path("/proc/sys")
    assert not os.access(target, os.W_OK)
    try:
        status, out, err = run(capsys, REFERENCE, REFERENCE, "--report", target / "report")
    finally:
        folder.chmod(0o700)
    assert status == 2 and "not writable" in err and out == ""


def test_report_or_junit_pointing_at_the_wrong_kind_of_path_is_bad_input_before_comparing(tmp_path, capsys):
    a_file = tmp_path / "a-file.txt"
    a_file.write_text("mine\n")
    status, out, err = run(capsys, REFERENCE, REFERENCE, "--report", a_file)
    assert status == 2 and "is a file, expected a folder" in err and out == ""
    assert a_file.read_text() == "mine\n"
    status, out, err = run(capsys, REFERENCE, REFERENCE, "--junit", tmp_path)
    assert status == 2 and "is a folder" in err and out == ""
    status, out, err = run(capsys, REFERENCE, REFERENCE, "--junit", tmp_path / "missing" / "v.xml")
    assert status == 2 and "no folder" in err and out == ""


def test_an_incomplete_actual_is_a_failing_test_case_complete(tmp_path, capsys):
    frame, meta = read_trace(REFERENCE)
    incomplete = tmp_path / "incomplete.parquet"
    write_trace(frame, incomplete, {**meta, "complete": "false", "reason": "failed"})
    junit = tmp_path / "verdicts.xml"
    assert run(capsys, incomplete, REFERENCE, "--junit", junit)[0] == 1
    (suite,) = list(junitparser.JUnitXml.fromfile(str(junit)))
    assert (suite.tests, suite.failures) == (8, 1)
    (case,) = [case for case in suite if case.result]
    assert case.name == "complete" and "complete: false" in case.result[0].message
