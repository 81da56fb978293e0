"""Tests of ``heliostep compare`` run in-process through heliostep.cli.main."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from heliostep.cli import main
from heliostep.results.trace.files import write_trace

T = np.linspace(0.0, 10.0, 1001)


def frame(**signals) -> pd.DataFrame:
    return pd.DataFrame({"time": T, **signals})


@pytest.fixture
def traces(tmp_path):
    """Reference (Parquet) and an equal actual (CSV) with three signals."""
    signals = {"motor.tau": np.sin(T), "panel_angle_error": np.cos(T), "rate": 0.5 * T}
    ref = tmp_path / "ref.parquet"
    act = tmp_path / "act.csv"
    write_trace(frame(**signals), ref, {"complete": "true", "unit.motor.tau": "N.m"})
    write_trace(frame(**signals), act, {"complete": "true"})
    return act, ref, signals


def run(capsys, *args) -> tuple[int, str, str]:
    status = main(["compare", *map(str, args)])
    out, err = capsys.readouterr()
    return status, out, err


def test_identical_traces_exit_0(traces, capsys):
    act, ref, _ = traces
    status, out, err = run(capsys, act, ref)
    assert status == 0, err
    assert "PASS" in out
    for name in ("motor.tau", "panel_angle_error", "rate"):
        assert name in out


def test_deviation_exit_1_and_table_names_signal_and_time(traces, tmp_path, capsys):
    _, ref, signals = traces
    bumped = dict(signals)
    bumped["motor.tau"] = np.where((T >= 2.0) & (T <= 2.1), np.sin(T) + 0.1, np.sin(T))
    act = tmp_path / "bumped.parquet"
    write_trace(frame(**bumped), act)
    status, out, _ = run(capsys, act, ref)
    assert status == 1
    row = next(line for line in out.splitlines() if line.startswith("motor.tau"))
    assert "FAIL" in row
    at_t = float(row.split()[3])  # signal, verdict, excess, time
    assert 2.0 <= at_t <= 2.1
    assert "FAIL: 1 of 3" in out
    assert next(line for line in out.splitlines() if line.startswith("rate")).split()[1] == "ok"


def test_signal_selection(traces, tmp_path, capsys):
    _, ref, signals = traces
    changed = dict(signals, rate=signals["rate"] + 1.0)
    act = tmp_path / "changed.csv"
    write_trace(frame(**changed), act)
    assert run(capsys, act, ref)[0] == 1
    status, out, _ = run(capsys, act, ref, "--signals", "motor.tau, panel_angle_error")
    assert status == 0
    assert "rate" not in out.split("PASS")[0].split("\n", 1)[1]


def test_tolerance_options_and_file(traces, tmp_path, capsys):
    _, ref, signals = traces
    # A ramp of slope 0.5 from t = 2 to 8; the actual reaches it 0.1 s early, so it
    # is up to 0.05 above the reference.
    ramp = np.clip(0.5 * (T - 2.0), 0.0, 3.0)
    write_trace(frame(**dict(signals, rate=ramp)), ref)
    act = tmp_path / "early.csv"
    write_trace(frame(**dict(signals, rate=np.clip(0.5 * (T - 1.9), 0.0, 3.0))), act)
    assert run(capsys, act, ref)[0] == 1
    assert run(capsys, act, ref, "--abs-tol", "0.06")[0] == 0
    assert run(capsys, act, ref, "--abs-tol", "0.04")[0] == 1
    assert run(capsys, act, ref, "--time-tol", "0.11")[0] == 0
    assert run(capsys, act, ref, "--time-tol", "0.09")[0] == 1
    tol = tmp_path / "tol.yaml"
    tol.write_text("default: {abs: 1e-6, rel: 0, time: 0}\nsignals:\n  rate: {abs: 0.06}\n")
    assert run(capsys, act, ref, "--tolerances", tol)[0] == 0
    tight = tmp_path / "tight.yaml"
    tight.write_text("signals:\n  rate: {abs: 0.04}\n")
    assert run(capsys, act, ref, "--tolerances", tight)[0] == 1


def test_incomplete_actual_exits_1(traces, tmp_path, capsys):
    """The ``trace.csv`` of a run that failed: its metadata.json says so (``trace``: the trace's metadata)."""
    _, ref, signals = traces
    act = tmp_path / "failed_run" / "trace.csv"
    act.parent.mkdir()
    write_trace(frame(**signals), act)
    (act.parent / "metadata.json").write_text(json.dumps({"complete": False, "trace": {"complete": "false"}}))
    status, out, _ = run(capsys, act, ref)
    assert status == 1
    assert "complete: false" in out


# --------------------------------------------------------------------------- bad input: exit 2


def _expect_input_error(capsys, args, *needles) -> str:
    status, out, err = run(capsys, *args)
    assert status == 2, out + err
    assert err.startswith("heliostep compare: error:")
    for needle in needles:
        assert str(needle) in err
    return err


def test_missing_signal(traces, capsys):
    act, ref, _ = traces
    _expect_input_error(capsys, [act, ref, "--signals", "motor.tau,motor.omega"], ref, "'motor.omega'")


def test_signal_missing_in_actual(traces, tmp_path, capsys):
    _, ref, signals = traces
    act = tmp_path / "partial.csv"
    write_trace(frame(**{"motor.tau": signals["motor.tau"]}), act)
    _expect_input_error(capsys, [act, ref, "--signals", "rate"], act, "'rate'")


def test_decreasing_time(traces, tmp_path, capsys):
    _, ref, _ = traces
    act = tmp_path / "backwards.csv"
    act.write_text("time,motor.tau\n0,0\n2,1\n1,2\n")
    _expect_input_error(capsys, [act, ref], act, "'time'", "decreases")


def test_nan_in_signal(traces, tmp_path, capsys):
    _, ref, signals = traces
    broken = dict(signals)
    broken["panel_angle_error"] = np.where(T == T[500], np.nan, signals["panel_angle_error"])
    act = tmp_path / "nan.parquet"
    write_trace(frame(**broken), act)
    _expect_input_error(capsys, [act, ref], act, "'panel_angle_error'", "NaN")


def test_missing_time_column(traces, tmp_path, capsys):
    act, _, _ = traces
    ref = tmp_path / "no_time.csv"
    ref.write_text("t,motor.tau\n0,0\n")
    _expect_input_error(capsys, [act, ref], ref, "'time'")


def test_missing_file(traces, tmp_path, capsys):
    act, _, _ = traces
    missing = tmp_path / "missing.parquet"
    _expect_input_error(capsys, [act, missing], missing, "no such file")


def test_unreadable_file(traces, tmp_path, capsys):
    _, ref, _ = traces
    garbage = tmp_path / "garbage.parquet"
    garbage.write_bytes(b"\x00\x01 definitely not parquet")
    _expect_input_error(capsys, [garbage, ref], garbage, "cannot read")


def test_bad_tolerance_inputs(traces, tmp_path, capsys):
    act, ref, _ = traces
    _expect_input_error(capsys, [act, ref, "--abs-tol", "-1"], "--abs-tol")
    _expect_input_error(capsys, [act, ref, "--time-tol", "soon"], "--time-tol")
    tol = tmp_path / "tol.yaml"
    tol.write_text("signals:\n  motor.tau: {abs: 1e-3, tolerance: 2}\n")
    _expect_input_error(capsys, [act, ref, "--tolerances", tol], tol, "'tolerance'")


# --------------------------------------------------------------------------- report


def test_report_has_index_and_one_png_per_failing_signal(traces, tmp_path, capsys):
    _, ref, signals = traces
    bad = dict(signals)
    bad["motor.tau"] = signals["motor.tau"] + 0.5
    bad["rate"] = np.where(T > 7.0, signals["rate"] + 1.0, signals["rate"])
    act = tmp_path / "bad.csv"
    write_trace(frame(**bad), act)
    report = tmp_path / "report"
    status, out, _ = run(capsys, act, ref, "--report", report)
    assert status == 1
    assert sorted(p.name for p in report.glob("*.png")) == ["motor.tau.png", "rate.png"]
    for png in report.glob("*.png"):
        assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    md = (report / "index.md").read_text()
    html = (report / "index.html").read_text()
    for index in (md, html):
        for name in ("motor.tau", "panel_angle_error", "rate"):
            assert name in index
        assert "panel_angle_error.png" not in index
    assert "(motor.tau.png)" in md and "(rate.png)" in md  # the Markdown twin links the PNGs
    # the HTML embeds its two figures (self-contained: tests/plots/test_compare_report.py decodes them)
    assert ".png" not in html and html.count('src="data:image/png;base64,') == 2


def test_report_for_passing_run_has_no_png(traces, tmp_path, capsys):
    act, ref, _ = traces
    report = tmp_path / "report"
    assert run(capsys, act, ref, "--report", report)[0] == 0
    assert list(report.glob("*.png")) == []
    assert "PASS" in (report / "index.md").read_text()


def _excel_csv(path, signals, sep, decimal, bom):
    header = sep.join(["time", *signals])
    rows = []
    for i, t in enumerate(T):
        cells = [repr(float(t)), *(repr(float(v[i])) for v in signals.values())]
        rows.append(sep.join(c.replace(".", decimal) for c in cells))
    path.write_text(("\ufeff" if bom else "") + "\r\n".join([header, *rows]) + "\r\n", encoding="utf-8")
    return path


@pytest.mark.parametrize(
    "sep, decimal, bom", [(",", ".", True), (";", ",", False), (";", ",", True), (";", ".", False)]
)
def test_excel_csv_with_bom_or_semicolons_is_compared(traces, tmp_path, capsys, sep, decimal, bom):
    _, ref, signals = traces
    act = _excel_csv(tmp_path / "excel.csv", signals, sep, decimal, bom)
    status, out, err = run(capsys, act, ref, "--abs-tol", "0", "--rel-tol", "0", "--time-tol", "0")
    assert status == 0, err
    assert "PASS: all 3 signal(s)" in out  # bit-exact values, every column found


def test_reference_signal_missing_from_actual_is_exit_2_unless_signals_are_selected(traces, tmp_path, capsys):
    _, ref, signals = traces
    act = tmp_path / "one-signal.csv"
    write_trace(frame(**{"motor.tau": signals["motor.tau"]}), act)
    status, printed, err = run(capsys, act, ref)
    assert status == 2 and "PASS" not in printed
    assert str(act) in err and "'panel_angle_error'" in err and "'rate'" in err and "--signals" in err
    status, out, _ = run(capsys, act, ref, "--signals", "motor.tau")
    assert status == 0 and "PASS: all 1 signal(s)" in out


def test_signal_only_in_actual_is_listed_not_an_error(traces, tmp_path, capsys):
    _, ref, signals = traces
    act = tmp_path / "more.csv"
    write_trace(frame(**signals, extra=T), act)
    status, out, _ = run(capsys, act, ref)
    assert status == 0 and "not compared, only in" in out and "extra" in out
