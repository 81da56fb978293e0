"""Python's cyclic garbage collector kept off the objects a command's imports make (:func:`imports_frozen`).

A command's modules (numpy, pandas, scipy, pyarrow, pydantic, fmpy and heliostep's own for ``heliostep
run``; matplotlib too in its figures' drawer) make about 195 000 objects that the garbage collector
tracks, and they live as long as the process. CPython's collector examines every one of them at each
full collection (81 ms for those of ``heliostep.cli.run``), and its middle generation sees them pass on
the way. In the whole ``heliostep run`` of the paper's case that was 2 full, 24 middle and 263 young
collections, 0.10-0.14 s (counted with :data:`gc.callbacks`), nearly all while importing; the drawer had
one full collection more (70 ms) when its job had just arrived, on the figures' critical path.

:func:`imports_frozen` runs the imports with the collector off, then freezes everything alive
(:func:`gc.freeze`: moved into a permanent generation that no collection examines) and turns the
collector back on: from then on it collects what the command makes, as usual. This is what
Python's documentation of :func:`gc.freeze` advises for a process that forks (since 3.11,
gh-103059): disable the collector early in the parent, freeze before ``fork()``, enable it again, so
that collections do not write to the inherited objects' headers either, whose pages the children
would then copy. What the imports leave as cyclic garbage stays, frozen: 1 883 objects for those of
``heliostep.cli.run`` (``gc.collect()`` after them), 3 MB of peak memory.

Used by the installed command (:func:`heliostep.cli.console_main`) around the import of its command's
modules, and by a forked helper around its preparation (:class:`heliostep.run.forked.Helper`).
"""

from __future__ import annotations

import contextlib
import gc
from collections.abc import Iterator

__all__ = ["imports_frozen"]


@contextlib.contextmanager
def imports_frozen() -> Iterator[None]:
    """The block run with the cyclic garbage collector off; on leaving it (also by an exception),
    everything alive frozen (:func:`gc.freeze`) and the collector on again if it was on before."""
    was_enabled = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        gc.freeze()
        if was_enabled:
            gc.enable()
