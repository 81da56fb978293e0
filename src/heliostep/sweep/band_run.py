"""An uncertainty band run: the design's samples on Dask, their figures, and ``summary.json``'s ``band``.

Details: docs/sweep.md, ``heliostep.sweep.band_run``.
"""

from __future__ import annotations

import copy
import dataclasses
import hashlib
import json
import math
import time as clock
import uuid
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any, TypeGuard

import numpy as np

from heliostep.errors import InputError
from heliostep.results.output.files import write_text_atomic
from heliostep.run import RunFailed, RunOptions, run_scenario
from heliostep.run.estimate import estimate_run
from heliostep.run.runner import HELD_TRACE_MAX_DURATION
from heliostep.scenario import Scenario, validate_scenario
from heliostep.sweep.band import BandDesign
from heliostep.sweep.band_composed import band_ways, certificate_failures, certify_sample, composed_sample
from heliostep.sweep.certificate import CERTIFIED_FIGURES
from heliostep.sweep.cluster import _dask_client, _worker_count
from heliostep.sweep.worker import FmuPayload, _error_text, _fmu_payload, _local_fmu

__all__ = [
    "BandOutcome",
    "band_figures",
    "run_figures",
    "band_composition",
    "band_record",
    "check_band_budget",
    "run_band",
    "write_band_summary",
]

#: Seconds between looks at the stop request while the samples run.
STOP_POLL = 0.25


@dataclasses.dataclass
class BandOutcome:
    """What :func:`run_band` did: each sample's result (index order), and whether it was stopped.

    ``results[i]`` is None for a sample that did not finish (the band stopped), else a dict with
    ``status`` ("ok" or "failed"), ``figures`` (:func:`band_figures`; None when failed), ``error``,
    ``wall_time_s`` [s], ``method`` (full, composed or certificate), ``fallback`` (why a sample to compose
    ran in full) and, on a certificate's, ``deviations``. ``ways``: how each sample was to run
    (:func:`~heliostep.sweep.band_composed.band_ways`), ``in_full_why`` why none was composed, and
    ``certificate_failed`` the figures on which the certificate failed (the composed samples then ran in full).
    """

    design: BandDesign
    results: list[dict[str, Any] | None]
    interrupted: bool = False
    ways: list[str] = dataclasses.field(default_factory=list)
    in_full_why: str | None = None
    certificate_failed: list[str] = dataclasses.field(default_factory=list)

    @property
    def finished(self) -> list[int]:
        return [index for index, result in enumerate(self.results) if result is not None]

    @property
    def failed(self) -> list[int]:
        return [index for index, result in enumerate(self.results) if result is not None and result["status"] != "ok"]


def band_figures(summary: Mapping[str, Any]) -> dict[str, float]:
    """The figures of a run summary that are numbers, by name; a mapping's numbers as ``name.key``
    (``settling_time_s.max``). Booleans, texts, lists and None are left out."""
    figures: dict[str, float] = {}
    for name, value in summary.items():
        if isinstance(value, Mapping):
            for key, inner in value.items():
                if _is_number(inner):
                    figures[f"{name}.{key}"] = float(inner)
        elif _is_number(value):
            figures[name] = float(value)
    return figures


def run_figures(result) -> dict[str, float]:
    """A run's band figures: :func:`band_figures` of its summary, and the solver's work from its
    statistics: ``solver.rhs`` (right-hand-side evaluations) and ``solver.rhs_per_step`` (per step
    commanded; left out without steps)."""
    figures = band_figures(result.summary)
    rhs = (result.metadata.get("statistics") or {}).get("rhs")
    if _is_number(rhs):
        figures["solver.rhs"] = float(rhs)
        steps = result.summary.get("steps_commanded")
        if _is_number(steps) and steps > 0:
            figures["solver.rhs_per_step"] = float(rhs) / float(steps)
    return figures


def _is_number(value: Any) -> TypeGuard[float]:
    return not isinstance(value, bool) and isinstance(value, (int, float)) and math.isfinite(value)


def run_band_sample(
    index: int, data: dict, source: str, folder: str, payloads: Mapping[str, FmuPayload], way: str = "full"
) -> dict:
    """One sample (a Dask task): its FMUs written locally, then as ``way`` says (:func:`band_ways`): run
    supervised (``full``), composed from its step family (``composed``; run where it falls back, ``fallback``
    says why), or both (``certificate``: the full run's figures, the composition's ``deviations``).

    Never raises for a failing run: its ``status`` is "failed" with the error's text."""
    started = clock.perf_counter()
    result: dict[str, Any] = {"index": index, "status": "ok", "figures": None, "error": None, "method": way}
    try:
        data = copy.deepcopy(data)
        data["fmus"] = {
            instance: None if sha is None else str(_local_fmu(payloads[sha])) for instance, sha in data["fmus"].items()
        }
        scenario = validate_scenario(data, source=source, folder=Path(folder))
        composed, fallback = None, None
        if way != "full":
            try:
                composed, fallback = composed_sample(scenario)
            except Exception as exc:  # noqa: BLE001 - the sample runs in full, which reports what is wrong
                fallback = f"not composed: {_error_text(exc)[:200]}"
        if way == "composed" and composed is not None:
            result["figures"] = band_figures(composed)
        else:
            run = run_scenario(scenario, RunOptions(keep_trace=False, supervise=True))
            result["figures"] = run_figures(run)
            result.update(method="full" if way == "composed" else way, fallback=fallback)
            if way == "certificate" and composed is not None:  # one that fell back certifies nothing
                result["deviations"] = certify_sample(run.summary, composed)
    except RunFailed as exc:
        result.update(status="failed", error=_error_text(exc))
    except Exception as exc:  # noqa: BLE001 - a failing sample is recorded, never fatal
        result.update(status="failed", error=f"{type(exc).__name__}: {_error_text(exc)}")
    result["wall_time_s"] = clock.perf_counter() - started
    return result


def _shipped_samples(
    scenario: Scenario, design: BandDesign, fmu_paths: Mapping[str, Path]
) -> tuple[list[tuple[int, dict, str]], dict[str, FmuPayload]]:
    """Each sample's validated scenario as data (its ``fmus`` the SHA-256 of the FMU files), and the FMUs."""
    payloads: dict[str, FmuPayload] = {}
    sha_of: dict[str, str] = {}
    for instance, path in fmu_paths.items():
        fmu_bytes = Path(path).read_bytes()
        sha = hashlib.sha256(fmu_bytes).hexdigest()
        payloads[sha] = FmuPayload(name=Path(path).name, sha256=sha, data=fmu_bytes)
        sha_of[instance] = sha
    samples = []
    for index in range(design.samples):
        sample = design.scenario_of(scenario, index)  # an InputError names the sample, before any run
        data = sample.resolved_dict()
        data["fmus"] = {instance: sha_of.get(instance) for instance in data["fmus"]}
        samples.append((index, data, sample.source))
    return samples, payloads


def run_band(
    scenario: Scenario,
    design: BandDesign,
    fmu_paths: Mapping[str, Path],
    *,
    client=None,
    scheduler: str | None = None,
    n_workers: int | None = None,
    connect_timeout: float = 5.0,
    should_stop: Callable[[], bool] | None = None,
    on_sample: Callable[[dict], None] | None = None,
    exact: bool = False,
) -> BandOutcome:
    """Run the design's samples of ``scenario`` on Dask, composed from their step families where that pays
    (:func:`~heliostep.sweep.band_composed.band_ways`), certified by samples run in full.

    Parameters
    ----------
    scenario : Scenario
        The nominal scenario.
    design : BandDesign
        From :func:`heliostep.sweep.band.band_design`.
    fmu_paths : Mapping
        Instance -> FMU file (:func:`heliostep.run.resolve_fmus`), shipped to the workers.
    client, scheduler, n_workers, connect_timeout
        As :func:`heliostep.sweep.execute_cases`: a client, a scheduler's address, or a new local
        cluster on 127.0.0.1 with ``n_workers`` workers (default one per core).
    should_stop : callable, optional
        Asked every :data:`STOP_POLL` s; once true the samples not finished are cancelled.
    on_sample : callable, optional
        Called with each finished sample's result (a composed one once the certificate is in).
    exact : bool
        Every sample co-simulated in full.

    Returns
    -------
    BandOutcome
    """
    samples, payloads = _shipped_samples(scenario, design, fmu_paths)
    ways, why = band_ways(scenario, design, exact)
    outcome = BandOutcome(design, [None] * design.samples, ways=ways, in_full_why=why)
    if should_stop is not None and should_stop():  # stopped before the cluster starts
        outcome.interrupted = True
        return outcome
    with _dask_client(client, scheduler, n_workers, connect_timeout) as dask:  # Ctrl+C: sweep.local_worker
        submit, shipped = _submitter(dask, samples, payloads, str(scenario.folder))
        try:
            _Collector(dask, submit, outcome, should_stop, on_sample).run()
        finally:
            for future in shipped:
                future.release()
    return outcome


def _submitter(dask, samples: list[tuple[int, dict, str]], payloads: Mapping[str, FmuPayload], folder: str):
    """The FMUs shipped once, and ``submit(index, way)``: the future of one sample's task (and the FMUs'
    futures)."""
    run_id = uuid.uuid4().hex[:12]
    shipped = {
        sha: dask.submit(_fmu_payload, payload, key=f"heliostep-band-fmu-{sha[:16]}-{run_id}", pure=False)
        for sha, payload in payloads.items()
    }

    def submit(index: int, way: str):
        _, data, source = samples[index]
        needed = {sha: shipped[sha] for sha in set(data["fmus"].values()) if sha is not None}
        key = f"heliostep-band-{index}-{way}-{run_id}"
        return dask.submit(run_band_sample, index, data, source, folder, needed, way, pure=False, key=key)

    return submit, list(shipped.values())


class _Collector:
    """Each sample's result into the outcome as it finishes; a composed one held until the certificate's
    samples are in, then kept or, where the certificate fails, its sample run again in full. Once
    ``should_stop()`` the rest are cancelled (held compositions with them: not certified, not kept)."""

    def __init__(self, dask, submit, outcome: BandOutcome, should_stop, on_sample) -> None:
        self.dask, self.submit, self.outcome = dask, submit, outcome
        self.should_stop, self.on_sample = should_stop, on_sample
        self.futures = {submit(index, way): index for index, way in enumerate(outcome.ways)}
        self.waiting = outcome.ways.count("certificate")
        self.held: list[dict] = []

    def run(self) -> None:
        from distributed import wait

        pending = set(self.futures)
        while pending:
            if self.should_stop is not None and self.should_stop():
                self.outcome.interrupted = True
                self.dask.cancel(list(pending))
                return
            try:
                done, pending = wait(pending, timeout=STOP_POLL, return_when="FIRST_COMPLETED")
            except TimeoutError:
                continue
            for future in done:
                pending |= self._take(future)

    def _take(self, future) -> set:
        """One finished task's result; the futures it submits (composed samples to run in full)."""
        index = self.futures.pop(future)
        try:
            result = future.result()
        except Exception as exc:  # noqa: BLE001 - e.g. KilledWorker: recorded as the sample's failure
            result = {"index": index, "status": "failed", "figures": None, "error": _error_text(exc)}
            result["wall_time_s"] = None
        future.release()
        if result["status"] != "ok" and self.should_stop is not None and self.should_stop():
            return set()  # ended by the stop (Ctrl+C reaches the local workers too): not run, not failed
        if result.get("method") == "composed":
            if self.outcome.certificate_failed:
                return self._in_full([index])
            if self.waiting:
                self.held.append(result)
                return set()
        self._keep(result)
        if self.outcome.ways[index] != "certificate":
            return set()
        self.waiting -= 1
        if self.waiting:
            return set()
        ways, results = self.outcome.ways, self.outcome.results
        certified = [  # a sample that failed has no deviations, and fails the certificate; one that fell back, none
            (results[i] or {}).get("deviations") or {}
            for i, way in enumerate(ways)
            if way == "certificate" and not (results[i] or {}).get("fallback")
        ]
        self.outcome.certificate_failed = certificate_failures(certified)
        held, self.held = self.held, []
        if self.outcome.certificate_failed:
            return self._in_full([r["index"] for r in held])
        for composed in held:
            self._keep(composed)
        return set()

    def _in_full(self, indices: list[int]) -> set:
        submitted = {self.submit(index, "full"): index for index in indices}
        self.futures.update(submitted)
        return set(submitted)

    def _keep(self, result: dict) -> None:
        self.outcome.results[result["index"]] = result
        if self.on_sample is not None:
            self.on_sample(result)


def check_band_budget(scenario: Scenario, samples: int, n_workers: int | None = None) -> None:
    """Refuse (InputError) a band whose samples, run at once on this machine's local cluster, would
    take more memory than ``budget.memory_gb``: each worker runs one sample at a time (figures
    only, no trace: :func:`~heliostep.run.estimate.estimate_run` with ``keep_trace=False``) beside
    the nominal run's process."""
    nominal = estimate_run(scenario, HELD_TRACE_MAX_DURATION)
    sample = estimate_run(scenario, HELD_TRACE_MAX_DURATION, keep_trace=False)
    at_once = min(samples, n_workers or _worker_count())
    needed = nominal.memory_bytes + at_once * sample.memory_bytes
    allowed = scenario.budget.memory_gb
    if needed > allowed * 1e9:
        raise InputError(
            f"{scenario.source}: --band {samples}: {at_once} samples at once need an estimated "
            f"{needed / 1e9:.3g} GB of memory (each {sample.describe()}), over the memory budget of "
            f"{allowed:g} GB (raise it with budget.memory_gb or --max-memory, or run fewer --workers)"
        )


def band_record(nominal_figures: Mapping[str, float], outcome: BandOutcome) -> dict[str, Any]:
    """``summary.json``'s ``band``: the design, each figure's nominal / min / median / max over the
    samples that finished, each sample's values, status and figures, and a note on what is missing.

    Parameters
    ----------
    nominal_figures : Mapping
        The nominal run's figures (:func:`run_figures`).
    outcome : BandOutcome
    """
    design = outcome.design
    ok = [result for result in outcome.results if result is not None and result["status"] == "ok"]
    figures = {}
    for name, value in nominal_figures.items():
        values = np.array([result["figures"][name] for result in ok if name in result["figures"]], dtype=float)
        entry: dict[str, Any] = {"nominal": value, "samples": int(values.size)}
        if values.size:
            entry.update(min=float(values.min()), median=float(np.median(values)), max=float(values.max()))
            entry["nominal_inside"] = bool(entry["min"] <= value <= entry["max"])
        figures[name] = entry
    record = {
        "complete": not outcome.interrupted and len(ok) == design.samples,
        "samples": design.samples,
        "finished": outcome.finished,
        "failed": outcome.failed,
        "interrupted": outcome.interrupted,
        "design": design.record(),
        "figures": figures,
        "sample_results": [
            {"index": index, "values": design.settings(index), **(result or {"status": "not run"})}
            for index, result in enumerate(outcome.results)
        ],
    }
    record["composition"] = band_composition(outcome)
    notes = band_notes(outcome)
    if notes:
        record["note"] = "; ".join(notes)
    return record


def band_composition(outcome: BandOutcome) -> dict[str, Any]:
    """How the samples were made: their count by method, why none was composed (``in_full``), and per
    certified figure the largest deviation on the certificate's samples with its tolerance."""
    finished = [result for result in outcome.results if result is not None]
    methods: dict[str, int] = {}
    for result in finished:
        methods[result.get("method") or "full"] = methods.get(result.get("method") or "full", 0) + 1
    certified = [result["deviations"] for result in finished if result.get("deviations")]
    return {
        "methods": methods,
        "in_full": outcome.in_full_why,
        "certificate_failed": outcome.certificate_failed,
        "certificate": {
            name: {"max_deviation": max((d[name] for d in certified), default=None), "tolerance": tolerance}
            for name, tolerance in CERTIFIED_FIGURES.items()
        }
        if certified
        else {},
    }


def band_notes(outcome: BandOutcome) -> list[str]:
    """What a reader of the band must know: samples failed or not run, nominal values outside their ranges."""
    design = outcome.design
    notes = []
    failed = outcome.failed
    if failed:
        notes.append(
            f"{len(failed)} of {design.samples} samples failed (sample(s) {', '.join(map(str, failed))}: "
            "see sample_results); the band is over the others"
        )
    composed = sum(1 for result in outcome.results if result is not None and result.get("method") == "composed")
    if composed:
        notes.append(
            f"{composed} samples composed from their step families carry the figures a family composes "
            '(docs/sweep.md, "Step families"); the band of the others is over the samples run in full'
        )
    missing = [index for index, result in enumerate(outcome.results) if result is None]
    if missing:
        notes.append(
            f"stopped: {len(outcome.finished)} of {design.samples} samples finished "
            f"({', '.join(map(str, outcome.finished)) or 'none'}); the band is over those"
        )
    for parameter in design.ranges:
        value = design.nominal[parameter.key]
        if not parameter.low <= value <= parameter.high:
            notes.append(
                f"the nominal {parameter.key} = {value:g} {parameter.unit} lies outside its range "
                f"{parameter.low:g}-{parameter.high:g} {parameter.unit}: the band is the spread over the "
                "range, not around the nominal run, and need not contain it"
            )
    return notes


def write_band_summary(out_dir: Path, record: Mapping[str, Any], band: Mapping[str, Any]) -> Path:
    """``summary.json`` again: the nominal run's ``record`` (:meth:`~heliostep.run.RunResult.summary_record`)
    with ``band`` added, renamed into place (the caller holds the folder's lock)."""
    text = json.dumps({**record, "band": dict(band)}, indent=2, default=str) + "\n"
    return write_text_atomic(Path(out_dir) / "summary.json", text)
