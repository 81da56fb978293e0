"""Issue #24: the termination an FMU asks for is said in stdout and in ``summary.json``, naming the
instance and the time (the mini Counter asks to terminate at its parameter ``t_stop``)."""

from __future__ import annotations

import json

import pytest

from heliostep.cli import main
from heliostep.paths import scenarios_dir

CENTRAL = scenarios_dir() / "jan21-central.yaml"


@pytest.fixture(scope="module")
def counter(tmp_path_factory):
    from third_party_fmu import build_mini_fmu

    return build_mini_fmu("Counter", tmp_path_factory.mktemp("counter"))


def test_an_fmu_that_terminates_is_named_with_its_time_in_stdout_and_summary_json(tmp_path, capsys, counter):
    out = tmp_path / "out"
    args = ["run", str(CENTRAL), "--out", str(out), "--no-plots", "--no-supervise", "--set", "window.duration=12"]
    assert main([*args, "--set", f"fmus.counter={counter}", "--set", "parameters.counter.t_stop=4.5"]) == 1
    stdout = capsys.readouterr().out
    assert "INCOMPLETE (terminated at t = 4.5 s)" in stdout
    assert "terminated by counter at t = 4.5 s" in stdout
    summary = json.loads((out / "summary.json").read_text())
    assert summary["complete"] is False and summary["reason"] == "terminated"
    assert summary["terminated"]["instances"] == ["counter"]
    assert summary["terminated"]["time_s"] == pytest.approx(4.5)
    assert "counter asked to terminate" in summary["terminated"]["by"]


def test_supervised_the_termination_is_said_the_same(tmp_path, capsys, counter):
    out = tmp_path / "out"
    args = ["run", str(CENTRAL), "--out", str(out), "--no-plots", "--set", "window.duration=12"]
    assert main([*args, "--set", f"fmus.counter={counter}", "--set", "parameters.counter.t_stop=3"]) == 1
    assert "terminated by counter at t = 3 s" in capsys.readouterr().out
    assert json.loads((out / "summary.json").read_text())["terminated"]["instances"] == ["counter"]


def test_an_fmu_that_does_not_terminate_leaves_no_termination_in_summary_json(tmp_path, capsys, counter):
    out = tmp_path / "out"
    args = ["run", str(CENTRAL), "--out", str(out), "--no-plots", "--no-supervise", "--set", "window.duration=6"]
    assert main([*args, "--set", f"fmus.counter={counter}", "--set", "parameters.counter.t_stop=100"]) == 0
    assert "terminated" not in capsys.readouterr().out
    assert "terminated" not in json.loads((out / "summary.json").read_text())
