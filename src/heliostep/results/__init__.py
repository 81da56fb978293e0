"""A run's results: the trace, its figures, trace files, comparison and regression.

:mod:`~heliostep.results.trace` (the master's rows plus reference, commanded position and
error), :mod:`~heliostep.results.run_figures` (a run's figures, in the one pass of its
simulation: :mod:`~heliostep.results.solution`, :mod:`~heliostep.results.steps`,
:mod:`~heliostep.results.summary`, typed in :mod:`~heliostep.results.run_summary`), the row sinks
(:mod:`~heliostep.results.row_sinks`, :mod:`~heliostep.results.trace_stream`), the output folder
(:mod:`~heliostep.results.run_files`, :mod:`~heliostep.results.outputs`),
:mod:`~heliostep.results.trace_io` (Parquet/CSV with metadata), :mod:`~heliostep.results.compare`
(tolerance tubes) and :mod:`~heliostep.results.regress` (shipped scenarios against their
references). May import :mod:`heliostep.drive`, :mod:`heliostep.scenario` and below; never
:mod:`heliostep.cli`, :mod:`heliostep.run` or :mod:`heliostep.plots` (but for the report
writer called on request).
"""
