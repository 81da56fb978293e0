"""The sizing's files: ``sizing.json`` and ``sizing.html`` in the output folder, which the sizing owns
as ``heliostep run`` owns its own (:mod:`heliostep.results.output.folder`: a lock for its life, the files
written into a staging folder and swapped in, a manifest of what it wrote).

An interrupted sizing still writes both, marked ``"complete": false``, with the cases it finished (and
their figures) and those it did not; its verdicts are ``incomplete`` where a case is missing.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable
from pathlib import Path

from heliostep.results.output.files import check_out_dir
from heliostep.results.output.folder import check_foreign, hold_folder, staging_folder, swap_in
from heliostep.sizing.plan import SizingPlan
from heliostep.sizing.size import judge_candidates, run_sizing_cases

__all__ = ["SIZING_FILES", "size"]

#: The files ``heliostep size`` writes.
SIZING_FILES = ("sizing.json", "sizing.html")


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
) -> dict:
    """Run the plan's cases, judge every candidate and write the sheet into ``out_dir``; the sheet."""
    from heliostep.plots.sizing import sizing_html  # here: matplotlib only when a sheet is drawn

    folder = check_out_dir(out_dir)
    with hold_folder(folder):
        check_foreign(folder, SIZING_FILES)
        results = run_sizing_cases(
            plan, scheduler=scheduler, progress=progress, should_stop=should_stop, on_case=on_case
        )
        stopped = len(results) < len(plan.cases)
        sheet = judge_candidates(plan, results, curves=not stopped)
        sheet = {
            "scenario": plan.scenario.name,
            "source": plan.scenario.source,
            "catalogue": catalogue,
            "wind": {"moment_Nm": plan.wind_moment, "source": plan.wind_source},
            "safety_factor": plan.safety_factor,
            "days": plan.days,
            "day_selection": plan.day_selection.record() if plan.day_selection is not None else None,
            "complete": not stopped,
            "finished_cases": [case.key for case in plan.cases if case.key in results],
            "unfinished_cases": [case.key for case in plan.cases if case.key not in results],
            **sheet,
        }
        staging = staging_folder(folder)
        (staging / "sizing.json").write_text(json.dumps(_json_safe(sheet), indent=1) + "\n", encoding="utf-8")
        (staging / "sizing.html").write_text(sizing_html(sheet), encoding="utf-8")
        swap_in(folder, staging, SIZING_FILES)
    return sheet
