"""The project's exception types.

Every error that comes from bad input derives from :class:`HeliostepError`, so the
command line can report it as one clear line and exit with status 2 instead of a
traceback.
"""


class HeliostepError(Exception):
    """Base class of the errors heliostep raises for bad input or failed runs."""


class InputError(HeliostepError, ValueError):
    """A parameter, file, key or variable is not what was expected."""
