"""``heliostep run --fail-on lost-steps,missed-steps``: a complete run whose summary counts the steps named
writes everything, then exits 3 (a status no other outcome has: docs/running.md), for a CI job. Real runs:
jan21-weak-motor misses all 16 of its steps and loses 64; jan21-central loses none."""

from __future__ import annotations

import json

import pytest

from heliostep.cli import main
from heliostep.cli.run import FAIL_ON_STATUS

FILES = {"trace.parquet", "trace.csv", "summary.json", "metadata.json"}


def _files(out) -> set[str]:
    return {path.name for path in out.iterdir() if not path.name.startswith(".")}


@pytest.mark.parametrize(
    "fail_on, said",
    [
        ("lost-steps,missed-steps", "64 lost steps, 16 missed steps"),
        ("missed-steps", "16 missed steps"),
        ("lost-steps", "64 lost steps"),
    ],
)
def test_lost_or_missed_steps_exit_3_after_writing_everything(fail_on, said, tmp_path, capsys):
    out = tmp_path / "out"
    status = main(["run", "jan21-weak-motor", "--no-plots", "--out", str(out), "--fail-on", fail_on])
    captured = capsys.readouterr()
    assert status == FAIL_ON_STATUS == 3
    assert f"heliostep run: --fail-on: {said} (exit 3)" in captured.err
    assert "missed steps                 16" in captured.out  # the figures printed as always
    summary = json.loads((out / "summary.json").read_text())
    assert summary["complete"] is True and (summary["missed_steps"], summary["steps_lost"]) == (16, 64)
    assert FILES <= _files(out)


def test_without_fail_on_the_same_run_exits_0(tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["run", "jan21-weak-motor", "--no-plots", "--out", str(out)]) == 0
    assert "--fail-on" not in capsys.readouterr().err and FILES <= _files(out)


def test_a_run_that_makes_every_step_exits_0(tmp_path, capsys):
    out = tmp_path / "out"
    args = ["run", "jan21-central", "--no-plots", "--set", "window.duration=60", "--out", str(out)]
    assert main([*args, "--fail-on", "lost-steps,missed-steps"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["steps_commanded"] > 0 and (summary["missed_steps"], summary["steps_lost"]) == (0, 0)


@pytest.mark.parametrize("fail_on", ["lost", "lost-steps,wrong-steps", "", "lost-steps,"])
def test_an_unknown_name_is_exit_2_before_anything_runs(fail_on, tmp_path, capsys):
    out = tmp_path / "out"
    with pytest.raises(SystemExit) as exited:
        main(["run", "jan21-weak-motor", "--out", str(out), "--fail-on", fail_on])
    err = capsys.readouterr().err
    assert exited.value.code == 2 and "argument --fail-on" in err and "lost-steps, missed-steps" in err
    assert not out.exists()
