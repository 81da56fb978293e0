"""Verdicts of a trace comparison in the forms CI servers read: JUnit XML and GitHub annotations.

Details: docs/compare.md, ``heliostep.results.compare.verdicts``.
"""

from __future__ import annotations

import math
import socket
import xml.etree.ElementTree as ET
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from datetime import UTC, datetime
from pathlib import Path

from heliostep.results.compare.traces import ComparisonResult, SignalResult

__all__ = ["SuiteVerdict", "failure_message", "github_annotations", "junit_xml"]

FAILURE_TYPE = "ToleranceTube"


@dataclass(frozen=True)
class SuiteVerdict:
    """One comparison for CI: a name (``compare``, or the scenario), its comparison (None when
    the run failed: *problem* says why), the units of its signals and whether the actual was
    complete."""

    name: str
    comparison: ComparisonResult | None
    units: Mapping[str, str] = field(default_factory=dict)
    problem: str | None = None
    complete: bool = True
    seconds: float = 0.0
    file: str = ""


def _quantity(value: float, unit: str | None) -> str:
    if not math.isfinite(value):
        return "-"
    return f"{value:.4g} {unit}" if unit else f"{value:.4g}"


def failure_message(result: SignalResult, unit: str | None = None, time_unit: str = "s") -> str:
    """Why *result* failed, in one line: the worst excess beyond the tube, its time, the deviation
    from the reference and the tube's half-width there (or the note, for a truncated actual)."""
    if result.passed:
        return "inside the tube"
    parts = []
    if math.isfinite(result.max_excess) and result.max_excess > 0:
        parts.append(
            f"outside the tube by {_quantity(result.max_excess, unit)} at t = {result.time_max_excess:.6g} "
            f"{time_unit}: actual - reference = {_quantity(result.deviation_at_max_excess, unit)}, "
            f"tube half-width there {_quantity(result.half_width_at_max_excess, unit)}"
        )
    if result.note:
        parts.append(result.note)
    parts.append(f"outside {100 * result.outside_fraction:.3g} % of the time")
    return "; ".join(parts)


def _details(result: SignalResult, unit: str | None, match: str) -> str:
    tol = result.tolerance
    return "\n".join(
        [
            failure_message(result, unit),
            f"compared: {match}",
            f"tolerance: abs {tol.abs:g}{' ' + unit if unit else ''}, rel {tol.rel:g}, time {tol.time:g} s",
            f"largest |actual - reference| {_quantity(result.max_abs_diff, unit)} "
            f"at t = {result.time_max_abs_diff:.6g} s",
        ]
    )


def _suite(parent: ET.Element, verdict: SuiteVerdict, timestamp: str, hostname: str, package: str, number: int) -> None:
    suite = ET.SubElement(
        parent, "testsuite", name=verdict.name, timestamp=timestamp, hostname=hostname, package=package, id=str(number)
    )
    properties = ET.SubElement(suite, "properties")
    comparison = verdict.comparison
    if comparison is not None:
        ET.SubElement(properties, "property", name="actual", value=comparison.actual_name)
        ET.SubElement(properties, "property", name="reference", value=comparison.reference_name)
    tests = failures = errors = 0
    if verdict.problem is not None:
        case = ET.SubElement(suite, "testcase", name="run", classname=verdict.name, time="0")
        ET.SubElement(case, "error", message=verdict.problem, type="RunFailure").text = verdict.problem
        tests, errors = 1, 1
    if comparison is not None:
        for name, result in comparison.signals.items():
            case = ET.SubElement(suite, "testcase", name=name, classname=verdict.name, time="0")
            tests += 1
            if not result.passed:
                unit = verdict.units.get(name)
                failure = ET.SubElement(case, "failure", message=failure_message(result, unit), type=FAILURE_TYPE)
                failure.text = _details(result, unit, comparison.match_of(name).describe())
                failures += 1
    if not verdict.complete:
        case = ET.SubElement(suite, "testcase", name="complete", classname=verdict.name, time="0")
        message = "the actual trace is marked complete: false (the run that wrote it failed)"
        ET.SubElement(case, "failure", message=message, type="IncompleteTrace").text = message
        tests, failures = tests + 1, failures + 1
    ET.SubElement(suite, "system-out")
    ET.SubElement(suite, "system-err")
    suite.set("tests", str(tests))
    suite.set("failures", str(failures))
    suite.set("errors", str(errors))
    suite.set("time", f"{verdict.seconds:.3f}")


def junit_xml(verdicts: Sequence[SuiteVerdict], name: str = "heliostep") -> str:
    """The JUnit XML document of *verdicts* (see the module for its structure): ``name`` is each suite's
    ``package``; the ``testsuites`` element has no attributes (Apache Ant's JUnit schema allows none)."""
    timestamp = datetime.now(UTC).replace(tzinfo=None).isoformat(timespec="seconds")
    hostname = socket.gethostname() or "localhost"
    root = ET.Element("testsuites")
    for number, verdict in enumerate(verdicts):
        _suite(root, verdict, timestamp, hostname, name, number)
    ET.indent(root)
    return '<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, encoding="unicode") + "\n"


def _from_root(file: str, root: Path | None) -> str:
    """``file`` as a path from ``root`` where it lies under it, else as given."""
    if root is None:
        return file
    try:
        return Path(file).resolve().relative_to(root).as_posix()
    except (ValueError, OSError):
        return file


def _escape_data(text: str) -> str:
    return text.replace("%", "%25").replace("\r", "%0D").replace("\n", "%0A")


def _escape_property(text: str) -> str:
    return _escape_data(text).replace(":", "%3A").replace(",", "%2C")


def github_annotations(verdicts: Sequence[SuiteVerdict], root: Path | None = None) -> list[str]:
    """One GitHub Actions ``::error`` workflow command per failing signal, run failure or
    incomplete trace, naming the file (the reference, or the scenario) and the signal; a file under
    ``root`` (the repository's root) by its path from there, as GitHub attaches annotations."""
    lines = []
    for verdict in verdicts:
        file = verdict.file or (verdict.comparison.reference_name if verdict.comparison else verdict.name)
        where = f"file={_escape_property(_from_root(file, root))}"
        if verdict.problem is not None:
            title = _escape_property(f"{verdict.name}: run failed")
            lines.append(f"::error {where},title={title}::{_escape_data(verdict.problem)}")
        if not verdict.complete:
            title = _escape_property(f"{verdict.name}: incomplete trace")
            lines.append(f"::error {where},title={title}::the actual trace is marked complete: false")
        for name, result in (verdict.comparison.signals if verdict.comparison else {}).items():
            if not result.passed:
                title = _escape_property(f"{verdict.name}: {name} outside its tolerance tube")
                message = failure_message(result, verdict.units.get(name))
                lines.append(f"::error {where},title={title}::{_escape_data(message)}")
    return lines
