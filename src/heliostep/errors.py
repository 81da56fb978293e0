"""The project's exception types: two families, chosen by type where an error is raised.

:class:`InputError`: the input is wrong (a parameter, file, key or variable); the command line prints
one line and exits with status 2. :class:`RunFailure`: the input was accepted but the run failed (a
build, an FMU, the solver); one line, status 1. Both derive from :class:`HeliostepError`, which nothing
raises itself (``tests/test_errors.py``).
"""


class HeliostepError(Exception):
    """Base class of the errors heliostep raises for bad input or failed runs."""


class InputError(HeliostepError, ValueError):
    """A parameter, file, key or variable is not what was expected (exit status 2)."""


class RunFailure(HeliostepError):
    """The input was accepted but the run failed: a build, an FMU or the solver (exit status 1)."""
