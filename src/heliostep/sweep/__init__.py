"""Sizing sweeps: many scenario runs on ``dask.distributed``, one Parquet row per case.

A *sweep* names a base scenario and the axes to vary; every combination of axis
values (``combine: product``, the default) or every position along the axes
(``combine: zip``) is one *case*: one :func:`heliostep.run.run_scenario` worth of work,
summarised by its figures (max tracking error, peak torque, ...). See ``docs/sweep.md``.

Sweep file::

    name: smoke                      # optional, default: the file's stem
    base: ../jan21-central.yaml      # relative to the sweep file
    combine: product                 # or zip
    axes:
      day_of_year: [21, 172]         # window.date in the base scenario's year; or "all"
      mirror: [0, 12]                # mirror.index (clears mirror.distance); or "all" (0 .. 12)
      sequencer.current: [5.5, 3.0]  # any dotted scenario key
    overrides: {output.interval: 0.5}  # applied to every case (optional)
    shared_primary: false            # true: add the field's shared primary drive (see heliostep.sweep.field)

Shorthand axes: ``day_of_year``, ``mirror``, ``motor`` (``fmus.motor``), ``mechanics``
(``fmus.mechanics``), ``current`` (``sequencer.current``), ``wind_moment``
(``wind.moment``). Numeric axes also take ``{start, stop, step}`` (stop included).

How a sweep runs
----------------
1. :func:`load_sweep` reads the file; :func:`expand_cases` builds and **validates every
   case's scenario** (base + overrides + axis values), so bad input raises
   :class:`~heliostep.errors.InputError` naming the sweep file and key before any case runs.
2. The FMUs are built once, in the client (:func:`heliostep.fmu.build.ensure_fmu`), and their
   bytes shipped to the workers as one small Dask task per FMU; each worker writes each
   FMU once into its local folder and the case's scenario points ``fmus.<instance>`` at
   that local copy.
3. Cases run on a local cluster (one single-threaded worker process per core, on
   127.0.0.1) or on an existing scheduler. Each finished case is written at once as a
   one-row Parquet *part* file beside the table (``results.parquet.parts/``); the parts
   are merged into ``results.parquet`` (atomically) every :data:`CONSOLIDATE_EVERY`
   seconds and at the end, so a stopped sweep loses nothing done.
4. A case's id is a hash of its fully resolved scenario; a rerun skips every case that
   already has a row with the same id and the same FMU contents (``ok`` rows, and
   ``failed`` rows unless ``retry_failed``). A case that fails is recorded with its error
   and never stops the sweep.

Modules: :mod:`~heliostep.sweep.spec` (sweep files, axes, cases), :mod:`~heliostep.sweep.worker`
(one case on a worker), :mod:`~heliostep.sweep.store` (the Parquet table),
:mod:`~heliostep.sweep.cluster` (Dask) and :mod:`~heliostep.sweep.field` (the 13-mirror field).
Sits above :mod:`heliostep.run` (each case is a run); only :mod:`heliostep.cli` is above it.
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
