"""Sizing sweeps: many scenario runs on ``dask.distributed``, one Parquet row per case.

A sweep names a base scenario and the axes to vary; each combination is one case (one
:func:`heliostep.run.run_scenario`), validated before any case runs, stored as it finishes and
skipped on a rerun. File format and how a sweep runs: docs/sweep.md.

Details: docs/sweep.md, ``heliostep.sweep``.
"""

import importlib

#: Each public name and the module that defines it: imported on first use (PEP 562), so that
#: importing one submodule (``heliostep run --band``'s constants) does not import Dask, the
#: Parquet table and the workers.
_PUBLIC = {
    "CASE_COLUMNS": "heliostep.sweep.store",
    "CENTRAL_MIRROR": "heliostep.sweep.spec",
    "COMBINE_MODES": "heliostep.sweep.spec",
    "CONSOLIDATE_EVERY": "heliostep.sweep.cluster",
    "FIELD_COLUMNS": "heliostep.sweep.field",
    "FIGURE_COLUMNS": "heliostep.sweep.store",
    "FmuPayload": "heliostep.sweep.worker",
    "ROLES": "heliostep.sweep.spec",
    "RUN_COLUMNS": "heliostep.sweep.store",
    "SHORTHAND_AXES": "heliostep.sweep.spec",
    "SweepAxis": "heliostep.sweep.spec",
    "SweepCase": "heliostep.sweep.spec",
    "SweepOutcome": "heliostep.sweep.cluster",
    "SweepSpec": "heliostep.sweep.spec",
    "check_results_owner": "heliostep.sweep.store",
    "default_results_path": "heliostep.sweep.store",
    "execute_cases": "heliostep.sweep.cluster",
    "expand_cases": "heliostep.sweep.spec",
    "field_sharing_errors": "heliostep.sweep.field",
    "load_sweep": "heliostep.sweep.spec",
    "primary_sharing_error": "heliostep.sweep.worker",
    "read_results": "heliostep.sweep.store",
    "run_case": "heliostep.sweep.worker",
    "run_field": "heliostep.sweep.field",
    "run_sweep": "heliostep.sweep.cluster",
    "summary_figures": "heliostep.sweep.worker",
    "sweep_from_scenario": "heliostep.sweep.spec",
    "sweep_metadata": "heliostep.sweep.spec",
}


def __getattr__(name: str):
    if name in _PUBLIC:
        return getattr(importlib.import_module(_PUBLIC[name]), name)
    raise AttributeError(f"module 'heliostep.sweep' has no attribute {name!r}")


__all__ = [
    "CASE_COLUMNS",
    "CENTRAL_MIRROR",
    "COMBINE_MODES",
    "CONSOLIDATE_EVERY",
    "FIELD_COLUMNS",
    "FIGURE_COLUMNS",
    "ROLES",
    "RUN_COLUMNS",
    "SHORTHAND_AXES",
    "FmuPayload",
    "SweepAxis",
    "SweepCase",
    "SweepOutcome",
    "SweepSpec",
    "check_results_owner",
    "default_results_path",
    "execute_cases",
    "expand_cases",
    "field_sharing_errors",
    "load_sweep",
    "primary_sharing_error",
    "read_results",
    "run_case",
    "run_field",
    "run_sweep",
    "summary_figures",
    "sweep_from_scenario",
    "sweep_metadata",
]
