"""A run's results, one subpackage per job: :mod:`~heliostep.results.trace` (the trace and its files),
:mod:`~heliostep.results.figures` (the figures of the solution and ``summary.json``),
:mod:`~heliostep.results.light` (light on the tube), :mod:`~heliostep.results.compare` (tolerance tubes,
CI verdicts, regression) and :mod:`~heliostep.results.output` (a command's output folder).

May import :mod:`heliostep.drive`, :mod:`heliostep.scenario` and below; never :mod:`heliostep.cli`,
:mod:`heliostep.run` or :mod:`heliostep.plots` (but for the report writer called on request).
"""
