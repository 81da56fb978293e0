"""Running a scenario: ``run_scenario``, heliostep's one public entry point (re-exported as
``heliostep.run_scenario``), with its :class:`RunOptions`.
"""

from heliostep.run.fmus import resolve_fmus
from heliostep.run.options import RunOptions
from heliostep.run.result import RunFailed, RunResult
from heliostep.run.runner import HELD_TRACE_MAX_DURATION, SINK_ROWS, VERSIONED_PACKAGES, run_scenario, run_versions

__all__ = [
    "HELD_TRACE_MAX_DURATION",
    "SINK_ROWS",
    "VERSIONED_PACKAGES",
    "RunFailed",
    "RunOptions",
    "RunResult",
    "resolve_fmus",
    "run_scenario",
    "run_versions",
]
