"""Thinning long series for drawing: keep what the eye must see, in order."""

from __future__ import annotations

import numpy as np


def thin(time: np.ndarray, *series: np.ndarray, max_buckets: int = 2000) -> np.ndarray:
    """Indices of the samples to draw: all when few; else, per time bucket, the first and last
    sample and the min and max of each series.

    Parameters
    ----------
    time : numpy.ndarray  [s]
        Non-decreasing.
    *series : numpy.ndarray
        Same length as ``time``; NaN is allowed (ignored for the extremes).
    max_buckets : int
        Number of time buckets; at most (2 + 2 × number of series) × ``max_buckets`` indices.

    Returns
    -------
    numpy.ndarray of int
        Increasing, so the drawing order (and the two rows of a step instant) is kept.
    """
    n = time.size
    if n <= (2 + 2 * len(series)) * max_buckets:
        return np.arange(n)
    span = time[-1] - time[0]
    if span <= 0.0:
        bucket = np.zeros(n, dtype=np.int64)
    else:
        bucket = np.minimum(((time - time[0]) * (max_buckets / span)).astype(np.int64), max_buckets - 1)
    starts = np.flatnonzero(np.r_[True, bucket[1:] != bucket[:-1]])
    lengths = np.diff(np.r_[starts, n])
    ends = starts + lengths - 1
    segment = np.repeat(np.arange(starts.size), lengths)
    keep = [starts, ends]
    for values in series:
        values = np.asarray(values, dtype=float)
        for reduce in (np.fmin, np.fmax):  # NaN-ignoring extremes of each bucket
            extreme = np.repeat(reduce.reduceat(values, starts), lengths)
            hits = np.flatnonzero(values == extreme)
            first_hit = np.r_[True, segment[hits][1:] != segment[hits][:-1]] if hits.size else hits.astype(bool)
            keep.append(hits[first_hit])
    return np.unique(np.concatenate(keep))
