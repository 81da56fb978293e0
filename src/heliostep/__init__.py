"""heliostep: co-simulation of the stepper drives of solar-tracking mirrors.

The one public entry point is :func:`run_scenario` (taking :class:`RunOptions`, returning a
:class:`RunResult`), re-exported from :mod:`heliostep.run`. The packages follow the data flow, one
stage each, kept so by the import-linter contracts in ``pyproject.toml`` (docs/architecture.md).
"""

from heliostep._version import __version__

__all__ = ["RunFailed", "RunOptions", "RunResult", "__version__", "run_scenario"]


def __getattr__(name: str):
    # PEP 562: `import heliostep` stays light; the entry point is imported on first use.
    if name in ("run_scenario", "RunOptions", "RunResult", "RunFailed"):
        from heliostep import run

        return getattr(run, name)
    raise AttributeError(f"module 'heliostep' has no attribute {name!r}")
