"""The sizing's files: ``sizing.json`` and ``sizing.html`` in the output folder, which the sizing owns
as ``heliostep run`` owns its own (:mod:`heliostep.results.output.folder`: a lock for its life, the files
written into a staging folder and swapped in, a manifest of what it wrote).

An interrupted sizing still writes both, marked ``"complete": false``, with the cases it finished (and
their figures) and those it did not; its verdicts are ``incomplete`` where a case is missing. A sheet the
folder cannot take (a full disk, a file-size limit, a folder gone read-only) is written as ``sizing.json`` into
a rescue folder instead (:mod:`heliostep.results.output.rescue`) and the sizing fails (:class:`SheetNotWritten`).
"""

from __future__ import annotations

import json
import math
import shutil
from collections.abc import Callable
from pathlib import Path

from heliostep.errors import RunFailure
from heliostep.results.output.files import check_out_dir
from heliostep.results.output.folder import check_foreign, hold_folder, staging_folder, swap_in
from heliostep.results.output.rescue import rescue_folder, write_text_parts
from heliostep.sizing.case import CERTIFIED_CASE_FIGURES
from heliostep.sizing.plan import SizingPlan
from heliostep.sizing.size import judge_candidates, run_sizing_cases
from heliostep.sweep.certificate import CERTIFICATE_CASES, CERTIFIED_FIGURES

__all__ = ["SIZING_FILES", "SheetNotWritten", "size"]

#: The files ``heliostep size`` writes.
SIZING_FILES = ("sizing.json", "sizing.html")


class SheetNotWritten(RunFailure):
    """The sheet could not be written into its folder ``failed`` (exit status 1); ``rescue``: the folder that took
    ``sizing.json`` instead (None: none did); ``sheet``: the sheet, every finished case in it."""

    def __init__(self, failed: Path, error: OSError, rescue: Path | None, sheet: dict):
        self.failed, self.error, self.rescue, self.sheet = failed, error, rescue, sheet
        why = f"{error.filename}: {error.strerror}" if error.filename else (error.strerror or str(error))
        kept = f"sizing.json was written to {rescue} instead" if rescue else "no folder could take sizing.json either"
        super().__init__(f"could not write the sizing sheet to {failed} ({why}); {kept}")


def _json_safe(value):
    """Infinities (a margin against no load) as the string "inf"; JSON has no infinity."""
    if isinstance(value, float) and math.isinf(value):
        return "inf" if value > 0 else "-inf"
    if isinstance(value, dict):
        return {key: _json_safe(item) for key, item in value.items()}
    if isinstance(value, list | tuple):
        return [_json_safe(item) for item in value]
    return value


def size(
    plan: SizingPlan,
    out_dir: str | Path,
    *,
    scheduler: str | None = None,
    progress: bool = False,
    should_stop: Callable[[], bool] | None = None,
    catalogue: str = "",
    on_case: Callable[[str, dict], None] | None = None,
    exact: bool = False,
    certify: int = CERTIFICATE_CASES,
    seed: int = 0,
) -> dict:
    """Run the plan's cases (``exact``, ``certify``, ``seed``: :func:`~heliostep.sizing.size.run_sizing_cases`),
    judge every candidate and write the sheet into ``out_dir``; the sheet."""
    from heliostep.plots.sizing import sizing_html  # here: matplotlib only when a sheet is drawn

    folder = check_out_dir(out_dir)
    with hold_folder(folder):
        check_foreign(folder, SIZING_FILES)
        results = run_sizing_cases(
            plan,
            scheduler=scheduler,
            progress=progress,
            should_stop=should_stop,
            on_case=on_case,
            exact=exact,
            certify=certify,
            seed=seed,
        )
        stopped = len(results) < len(plan.cases)
        sheet = judge_candidates(plan, results, curves=not stopped, should_stop=should_stop)
        stopped = stopped or (should_stop is not None and should_stop())  # the curves too, if asked meanwhile
        sheet = {
            "scenario": plan.scenario.name,
            "source": plan.scenario.source,
            "inputs": plan.inputs,
            "catalogue": catalogue,
            "wind": {"moment_Nm": plan.wind_moment, "source": plan.wind_source},
            "safety_factor": plan.safety_factor,
            "days": plan.days,
            "day_selection": plan.day_selection.record() if plan.day_selection is not None else None,
            "complete": not stopped,
            "finished_cases": [case.key for case in plan.cases if case.key in results],
            "unfinished_cases": [case.key for case in plan.cases if case.key not in results],
            "composition": composition_record(list(results.values())),
            **sheet,
        }
        record = json.dumps(_json_safe(sheet), indent=1) + "\n"
        _write_sheet(folder, record, sizing_html(sheet), plan.scenario.name, sheet)
    return sheet


def _write_sheet(folder: Path, record: str, html: str, name: str, sheet: dict) -> None:
    """``sizing.json`` (``record``) and ``sizing.html`` swapped into ``folder``; on an OSError the staging
    folder removed and ``record`` rescued (:class:`SheetNotWritten`): no finished case is lost."""
    staging = None
    try:
        staging = staging_folder(folder)
        (staging / "sizing.json").write_text(record, encoding="utf-8")
        (staging / "sizing.html").write_text(html, encoding="utf-8")
        swap_in(folder, staging, SIZING_FILES)
    except OSError as exc:
        if staging is not None:
            shutil.rmtree(staging, ignore_errors=True)
        raise SheetNotWritten(folder, exc, _rescue(name, record), sheet) from None


def _rescue(name: str, record: str) -> Path | None:
    """``record`` as ``sizing.json`` in a fresh rescue folder (in pieces under a file-size limit); None if
    no folder takes it."""
    folder = rescue_folder(f"{name}-sizing")
    if folder is None:
        return None
    try:
        write_text_parts(folder, "sizing.json", record)
    except OSError:
        return None
    return folder


def composition_record(records: list[dict]) -> dict:
    """How the day cases were made: their count by method (``full``, ``composed`` from the drive's step
    family, ``certificate``), and per certified figure the largest deviation on the certificate's cases with
    its tolerance (none without composed cases)."""
    methods: dict[str, int] = {}
    for record in records:
        methods[record.get("method") or "full"] = methods.get(record.get("method") or "full", 0) + 1
    certified = [record for record in records if record.get("method") == "certificate"]
    deviations = {
        name: {
            "max_deviation": max(
                (value for record in certified if (value := record[f"deviation_{name}"]) == value), default=None
            ),  # a certificate case that failed (nan) fails its family, whose days then ran in full
            "tolerance": CERTIFIED_FIGURES[name],
        }
        for name in CERTIFIED_CASE_FIGURES
    }
    return {"methods": methods, "certificate": deviations if methods.get("composed") else {}}
