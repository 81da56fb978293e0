"""Supervision: a run's master in a child process (`child`), started and watched by `supervisor` (crashes
and hangs named from the FMI call record of :mod:`heliostep.cosim.watch`); `allocator`: a Dask worker's heap
setting undone."""
