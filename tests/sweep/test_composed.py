"""A sweep composed from step families against the same sweep co-simulated in full (``exact``), on a real
two-worker Dask cluster: figure by figure within the certificate's tolerances, the certificate's rows the
full runs' own."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml
from distributed import Client, LocalCluster

from heliostep.paths import scenarios_dir
from heliostep.sweep import run_sweep
from heliostep.sweep.certificate import CERTIFIED_FIGURES, certificate_sample, row_deviation

#: 3 days x 3 end mirrors, 45 minutes each on a sweep case's grid: beyond the certificate's cases, more window
#: than a family needs to pay (heliostep.sweep.certificate.FAMILY_WORTH_S).
SWEEP = {
    "name": "composed",
    "base": str(scenarios_dir() / "jan21-central.yaml"),
    "combine": "product",
    "axes": {"day_of_year": [80, 172, 355], "mirror": [0, 9, 12]},
    "overrides": {"window.start": "10:00", "window.duration": 2700, "output.interval": 1.0, "output.step_detail": 0},
}


@pytest.fixture(scope="module")
def client(fmu_paths):
    with (
        LocalCluster(
            n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1", dashboard_address=":0"
        ) as cluster,
        Client(cluster) as dask_client,
    ):
        dask_client.wait_for_workers(2)
        yield dask_client


@pytest.fixture(scope="module")
def both_ways(client, tmp_path_factory) -> dict:
    folder = tmp_path_factory.mktemp("composed")
    path = folder / "composed.yaml"
    path.write_text(yaml.safe_dump(SWEEP, sort_keys=False))
    return {
        exact: run_sweep(path, folder / f"exact-{exact}.parquet", client=client, exact=exact, certify=3).table
        for exact in (True, False)
    }


def test_a_composed_sweep_agrees_with_the_full_one_figure_by_figure(both_ways):
    exact, composed = (both_ways[way].set_index("case_id") for way in (True, False))
    assert set(exact["method"]) == {"full"} and (exact["status"] == "ok").all()
    assert composed["method"].value_counts().to_dict() == {"composed": 6, "certificate": 3}
    for case_id, row in composed.iterrows():
        full = exact.loc[case_id]
        assert row["steps_commanded"] == full["steps_commanded"] > 0
        for name, tolerance in CERTIFIED_FIGURES.items():
            assert row_deviation(full, row, name) <= tolerance, (case_id, name, full[name], row[name])
        for name in ("load_torque_Nm", "holding_torque_Nm", "primary_sharing_error_max_deg", "duration_s"):
            assert row[name] == full[name], name  # computed from the scenario, without simulating, as in full


def test_the_certificate_rows_are_full_runs_and_carry_their_deviations(both_ways):
    exact, composed = (both_ways[way].set_index("case_id") for way in (True, False))
    certificate = composed[composed["method"] == "certificate"]
    assert certificate["day_of_year"].nunique() + certificate["mirror_index"].nunique() >= 4  # spread over both axes
    for case_id, row in certificate.iterrows():
        for name, tolerance in CERTIFIED_FIGURES.items():
            assert row[name] == exact.loc[case_id, name]  # co-simulated in full
            assert 0.0 <= row[f"deviation_{name}"] <= tolerance
    others = composed[composed["method"] != "certificate"]
    assert others.filter(like="deviation_").isna().all().all()


def test_a_rerun_of_a_composed_sweep_skips_every_case(client, both_ways, tmp_path_factory):
    folder = Path(tmp_path_factory.getbasetemp()) / "composed0"
    outcome = run_sweep(folder / "composed.yaml", folder / "exact-False.parquet", client=client)
    assert outcome.executed == 0 and outcome.skipped == 9


def test_the_certificate_is_spread_reproducible_and_left_out_where_a_family_would_not_pay():
    hour = 3600.0
    groups = {"year": [10 * hour] * 365, "short": [300.0] * 30, "few": [10 * hour] * 2}
    sample = certificate_sample(groups, certify=20, seed=7)
    assert sample == certificate_sample(groups, certify=20, seed=7) != certificate_sample(groups, certify=20, seed=8)
    assert sample["short"] is None  # 30 five-minute days: 2.5 h of window, less than a family costs
    assert sample["few"] is None  # no case left to compose beside its certificate
    picked = sample["year"]
    assert len(picked) == 19  # its share of 20 (365 of 397 cases), one in each 19th of the year
    # run k of 19 near-equal runs of 365 (19 or 20 days) begins at or after day 19 k and ends before 19 (k + 1) + 4
    assert all(19 * k <= day < 19 * (k + 1) + 4 for k, day in enumerate(picked)) and picked == sorted(set(picked))


def test_the_report_says_how_the_rows_were_made_and_the_largest_certified_deviations():
    import pandas as pd

    from heliostep.cli.sweep import _certificate_lines

    table = pd.DataFrame(
        {
            "method": ["composed", "certificate", "certificate", "full"],
            "fallback": [None, None, None, "wind by its speed (a load that changes over the day)"],
            **{f"deviation_{name}": [None, 1e-5, 3e-5, None] for name in CERTIFIED_FIGURES},
        }
    )
    lines = _certificate_lines(table)
    assert lines[0] == "  rows: 2 certificate, 1 composed, 1 full"
    assert "run in full instead of composed: 1 (most often: wind by its speed" in lines[1]
    assert lines[3].split() == ["peak_torque_Nm", "3.00e-05", "(5.0e-03)"]
    assert len(lines) == 3 + len(CERTIFIED_FIGURES)


def test_certify_below_one_is_refused_before_anything_runs(tmp_path):
    import subprocess
    import sys

    path = tmp_path / "composed.yaml"
    path.write_text(yaml.safe_dump(SWEEP, sort_keys=False))
    code = "from heliostep.cli import console_main; console_main()"
    command = [sys.executable, "-c", code, "sweep", str(path), "--certify", "0"]
    done = subprocess.run(command, capture_output=True, text=True, cwd=tmp_path)
    assert done.returncode == 2
    assert "--certify: 0: expected a whole number of cases >= 1" in done.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["composed.yaml"]  # no out/ folder made


class _Done:
    """A finished task as the collector takes it from its queue: its result, released once read."""

    def __init__(self, result):
        self._result, self.released = result, False

    def result(self):
        return self._result

    def release(self):
        self.released = True


class _Tasks:
    """The sweep's submitter as the collector sees it: each task's tag, and full runs asked for (none here)."""

    def __init__(self, cases):
        self.tags, self.run_id, self.cases, self.asked = {}, "r", {case.case_id: case for case in cases}, []

    def full(self, case, reason):
        self.asked.append((case.case_id, reason))
        return _Done(None)


def test_a_familys_composed_rows_are_written_as_they_come_once_its_certificate_holds():
    """The collector (heliostep.sweep.composed._Collector) holds a family's composed rows until its certificate
    is in, then writes them, and each later task's rows as soon as that task is back, not after the last one; a
    certificate that fails sends the rows held and each later one to a full run instead."""
    from heliostep.sweep.composed import FamilyPlan, _chunks, _Collector
    from heliostep.sweep.spec import SweepCase

    cases = [SweepCase(f"c{k}", k, {"case_id": f"c{k}"}, {}, "s", ".") for k in range(7)]
    chunks = _chunks(cases, [cases[1], cases[5]])
    assert [[case.case_id for case in chunk] for chunk in chunks] == [["c1", "c5"], ["c0", "c2", "c3", "c4", "c6"]]
    figures = {name: 1.0 for name in CERTIFIED_FIGURES}
    for off in (0.0, 1.0):  # a certificate that holds, then one whose composed torque is off by 100 %
        tasks, written, queue = _Tasks(cases), [], []
        plan = FamilyPlan({}, {"f": cases}, {"f": [cases[1], cases[5]]})
        collector = _Collector(tasks, plan, queue, lambda row, to=written: to.append((row["case_id"], row["method"])))
        composed = lambda ids, shift=0.0: (  # noqa: E731 - a compose task's result: rows, no fallback
            [{"case_id": i, **figures, "peak_torque_Nm": 1.0 + shift, "method": "composed"} for i in ids],
            [],
        )
        for task, tag in (
            (_Done(composed(["c1", "c5"], off)), ("compose", chunks[0], "f", None)),
            (_Done({"case_id": "c1", **figures, "status": "ok"}), ("full", cases[1], None, True)),
            (_Done(composed(["c0", "c2"])), ("compose", chunks[1][:2], "f", None)),
            (_Done({"case_id": "c5", **figures, "status": "ok"}), ("full", cases[5], None, True)),
            (_Done(composed(["c3", "c4", "c6"])), ("compose", chunks[1][2:], "f", None)),
        ):
            tasks.tags[task] = tag
            queue.append(task)
        progress = []
        collector.pending = _Watched(queue, progress, written)
        collector.collect()
        if not off:
            assert written[:2] == [("c1", "certificate"), ("c5", "certificate")]
            assert [case for case, _ in written[2:]] == ["c0", "c2", "c3", "c4", "c6"]
            # c0 and c2 are written when c5's full run completes the certificate, before the last task is read
            assert progress[3] == 4 and progress[4] == 7 and not tasks.asked
        else:
            assert written == [("c1", "certificate"), ("c5", "certificate")]
            assert [case for case, _ in tasks.asked] == ["c0", "c2", "c3", "c4", "c6"]
            assert all("certificate fails on peak_torque_Nm" in reason for _, reason in tasks.asked)


class _Watched(list):
    """The collector's queue, noting how many rows are written when each task is taken (and taking no new
    ones: the full runs asked for are only noted)."""

    def __init__(self, tasks, progress, written):
        super().__init__(tasks)
        self.progress, self.written = progress, written

    def __iter__(self):
        for task in list(super().__iter__()):
            yield task
            self.progress.append(len(self.written))

    def add(self, task):
        pass
