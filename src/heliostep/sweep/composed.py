"""A sweep's cases composed from step families (:mod:`heliostep.run.step_family`) on Dask, certified.

The cases that share a drive share a family: one task co-simulates it, tasks of :data:`COMPOSE_CHUNK`
cases compose their rows from it. A certificate, a sample of each family's cases spread over the sweep
(reproducible by seed), is also run in full; its rows carry each certified figure's deviation. A family
whose certificate exceeds a tolerance, or that cannot be built, has its cases run in full, as has every
case whose steps leave what a family assumes (its row's ``fallback`` says why). Method: docs/sweep.md.
"""

from __future__ import annotations

import dataclasses
import time as clock
from collections.abc import Callable, Mapping, Sequence

from heliostep.drive.inputs import prepare_inputs
from heliostep.run.step_family import StepFamily, build_family, compose_case, family_key, not_composable
from heliostep.scenario import validate_scenario
from heliostep.sweep.certificate import (
    CERTIFICATE_CASES,
    certificate_sample,
    certified_row,
    failed_figures,
    window_seconds,
)
from heliostep.sweep.spec import SweepCase
from heliostep.sweep.store import FIGURE_COLUMNS
from heliostep.sweep.worker import (
    FmuPayload,
    _error_text,
    _holding_torque,
    _lost_case_row,
    load_figures,
    local_scenario,
    primary_sharing_error,
    run_case,
    run_columns,
)

#: Cases composed per Dask task.
COMPOSE_CHUNK = 25


@dataclasses.dataclass(frozen=True)
class FamilyPlan:
    """How a sweep's cases run: ``full`` ones (case id -> why), and per family key its cases and the
    sample of them that certifies it."""

    full: dict[str, str]
    families: dict[str, list[SweepCase]]
    certificate: dict[str, list[SweepCase]]


def plan_families(cases: Sequence[SweepCase], certify: int = CERTIFICATE_CASES, seed: int = 0) -> FamilyPlan:
    """Group ``cases`` (FMUs shipped: ``fmu_sha256`` set) by drive and draw each group's certificate
    (:func:`~heliostep.sweep.certificate.certificate_sample`); a group too small for a family to pay runs in
    full, as does a case :func:`~heliostep.run.step_family.not_composable` refuses."""
    full: dict[str, str] = {}
    groups: dict[str, list] = {}
    for case in cases:
        scenario = validate_scenario(case.scenario, source=case.source, folder=case.folder)
        reason = not_composable(scenario)
        if reason is not None:
            full[case.case_id] = reason
        else:
            groups.setdefault(family_key(scenario, case.fmu_sha256), []).append((case, window_seconds(scenario)))
    sample = certificate_sample({key: [d for _, d in group] for key, group in groups.items()}, certify, seed)
    families, certificate = {}, {}
    for key, pairs in groups.items():
        group = [case for case, _ in pairs]
        if sample[key] is None:
            full.update({case.case_id: "too few cases for a family to pay" for case in group})
        else:
            families[key], certificate[key] = group, [group[k] for k in sample[key]]
    return FamilyPlan(full, families, certificate)


def family_task(case: SweepCase, payloads: Mapping[str, FmuPayload]) -> StepFamily:
    """The Dask task that builds the family of ``case``'s drive (its FMUs from ``payloads``)."""
    return build_family(local_scenario(case, payloads)[0], fmu_digests=case.fmu_sha256)


def compose_task(cases: Sequence[SweepCase], family: StepFamily, payloads: Mapping[str, FmuPayload], run_id: str):
    """The Dask task that composes ``cases`` from ``family``: per case its table row (method
    "composed"), or (case, why) when it falls back."""
    rows, fallbacks = [], []
    for case in cases:
        started = clock.perf_counter()
        try:
            scenario, local = local_scenario(case, payloads)
            inputs = prepare_inputs(scenario)
            composed = compose_case(scenario, family, inputs, case.fmu_sha256)
        except Exception as exc:  # noqa: BLE001 - the case runs in full, which reports what is wrong
            fallbacks.append((case, f"not composed: {_error_text(exc)[:200]}"))
            continue
        if composed.fallback is not None:
            fallbacks.append((case, composed.fallback))
            continue
        row = {**case.columns, **dict.fromkeys(FIGURE_COLUMNS), **composed.figures}
        motor = scenario.roles.instance_of("torque")
        row["holding_torque_Nm"] = _holding_torque(scenario, motor, local.get(motor) if motor else None)
        row.update(load_figures(scenario, local, row["holding_torque_Nm"], inputs))
        row.update(primary_sharing_error(scenario))
        rows.append(_finished(row, case, run_id, started, "composed"))
    return rows, fallbacks


def _finished(row: dict, case: SweepCase, run_id: str, started: float, method: str, fallback=None) -> dict:
    row.update(status="ok", error_type=None, error=None, method=method, fallback=fallback)
    row.update(run_columns(case, run_id, started))
    return row


def run_with_families(
    client,
    cases: Sequence[SweepCase],
    shipped: Mapping,
    record: Callable[[dict], None],
    run_id: str,
    certify: int,
    seed: int,
) -> int:
    """Run ``cases`` on ``client`` through their families (``shipped``: SHA-256 -> the FMU payload's
    future); each finished row goes to ``record``. Returns the cases recorded."""
    from distributed import as_completed

    plan = plan_families(cases, certify, seed)
    run = _Submitter(client, shipped, run_id, cases)
    by_id = run.cases
    pending = as_completed()
    for case_id, reason in plan.full.items():
        pending.add(run.full(by_id[case_id], reason))
    for key in plan.families:  # the certificate's full runs first: the longest tasks
        for case in plan.certificate[key]:
            pending.add(run.full(case, None, certificate=True))
    for key, group in plan.families.items():
        family = run.family(group[0])
        for chunk in _chunks(group, plan.certificate[key]):
            pending.add(run.compose(chunk, family, key))
    return _Collector(run, plan, pending, record).collect()


def _chunks(group: Sequence[SweepCase], certificate: Sequence[SweepCase]) -> list[list[SweepCase]]:
    """A family's compose tasks: its certificate's cases first (the family's rows are held until they are
    compared), then the rest in sweep order, :data:`COMPOSE_CHUNK` cases a task."""
    sample = {case.case_id for case in certificate}
    rest = [case for case in group if case.case_id not in sample]
    return [list(certificate)] + [rest[start : start + COMPOSE_CHUNK] for start in range(0, len(rest), COMPOSE_CHUNK)]


class _Submitter:
    """Submits a sweep's tasks, each future tagged with what it is."""

    def __init__(self, client, shipped: Mapping, run_id: str, cases: Sequence[SweepCase]):
        self.client, self.shipped, self.run_id = client, shipped, run_id
        self.tags: dict = {}
        self.cases = {case.case_id: case for case in cases}

    def _needed(self, cases: Sequence[SweepCase]) -> dict:
        return {sha: self.shipped[sha] for case in cases for sha in case.fmu_sha256.values()}

    def full(self, case: SweepCase, reason: str | None, certificate: bool = False):
        future = self.client.submit(
            run_case,
            case,
            self._needed([case]),
            self.run_id,
            pure=False,
            key=f"heliostep-case-{case.case_id}-{self.run_id}",
        )
        self.tags[future] = ("full", case, reason, certificate)
        return future

    def family(self, case: SweepCase):
        key = f"heliostep-family-{case.case_id}-{self.run_id}"
        return self.client.submit(family_task, case, self._needed([case]), pure=False, key=key)

    def compose(self, cases: Sequence[SweepCase], family, key: str):
        name = f"heliostep-compose-{cases[0].case_id}-{self.run_id}"
        future = self.client.submit(compose_task, cases, family, self._needed(cases), self.run_id, pure=False, key=name)
        self.tags[future] = ("compose", cases, key, None)
        return future


@dataclasses.dataclass
class _Family:
    """A family's progress: the certificate cases not back yet, rows held until the certificate is in, and then
    its verdict (``failed``: the figures it fails on)."""

    waiting: set
    composed: dict = dataclasses.field(default_factory=dict)  # case id -> composed row, held
    full: dict = dataclasses.field(default_factory=dict)  # certificate case id -> its full row
    fallen: dict = dataclasses.field(default_factory=dict)  # certificate case id -> why it was not composed
    certified: list = dataclasses.field(default_factory=list)
    failed: list | None = None  # None until the certificate is in


class _Collector:
    """Records each finished task's rows: a family's composed rows once its certificate holds (those composed
    before, then each as it comes), else its cases run in full."""

    def __init__(self, run: _Submitter, plan: FamilyPlan, pending, record: Callable[[dict], None]):
        self.run, self.pending, self.record, self.recorded = run, pending, record, 0
        self.states = {key: _Family({case.case_id for case in plan.certificate[key]}) for key in plan.families}
        self.sample = {case.case_id: key for key, group in plan.certificate.items() for case in group}

    def _record(self, row: dict) -> None:
        self.record(row)
        self.recorded += 1

    def collect(self) -> int:
        for future in self.pending:
            kind, cases, extra, certificate = self.run.tags.pop(future)
            try:
                result = future.result()
            except Exception as exc:  # noqa: BLE001 - a lost worker, a family that could not be built
                result = exc
            future.release()
            if kind == "full":
                self._full(cases, result, extra, certificate)
            else:
                self._composed(cases, result, self.states[extra])
        return self.recorded

    def _full(self, case: SweepCase, result, reason: str | None, certificate: bool) -> None:
        row = result if isinstance(result, dict) else _lost_case_row(case, result, self.run.run_id)
        row.update(method="full", fallback=reason)
        state = self.states[self.sample[case.case_id]] if certificate else None
        if state is None or case.case_id in state.fallen:
            if state is not None:
                row["fallback"] = state.fallen.pop(case.case_id)
            self._record(row)
            return
        state.full[case.case_id] = row
        self._certify(state)

    def _composed(self, cases: Sequence[SweepCase], result, state: _Family) -> None:
        if isinstance(result, Exception):
            rows, fallbacks = [], [(case, f"no family: {_error_text(result)[:200]}") for case in cases]
        else:
            rows, fallbacks = result
        state.composed.update({row["case_id"]: row for row in rows})
        for case, reason in fallbacks:
            if case.case_id in state.waiting:  # its full run is under way: recorded as a fallback, certifies nothing
                state.waiting.discard(case.case_id)
                if case.case_id in state.full:
                    self._record({**state.full.pop(case.case_id), "fallback": reason})
                else:
                    state.fallen[case.case_id] = reason
            else:
                self.pending.add(self.run.full(case, reason))
        self._certify(state)

    def _certify(self, state: _Family) -> None:
        """Record the certificate rows whose full and composed figures are both back; once the certificate is
        in, the composed rows held and each later one (it holds) or their full runs (it does not)."""
        for case_id in [c for c in state.waiting if c in state.full and c in state.composed]:
            state.waiting.discard(case_id)
            row = certified_row(state.full.pop(case_id), state.composed.pop(case_id))
            state.certified.append(row)
            self._record(row)
        if state.waiting:
            return
        if state.failed is None:
            state.failed = failed_figures(state.certified)
        if not state.failed:
            for row in state.composed.values():
                self._record(row)
        else:
            reason = f"the family's certificate fails on {', '.join(state.failed)}"
            for row in state.composed.values():
                self.pending.add(self.run.full(self.run.cases[row["case_id"]], reason))
        state.composed.clear()
