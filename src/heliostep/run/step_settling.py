"""A step's settling time as a family keeps it: the lobes of its ring, so that a case's steps between the
family's angles, and held at a load's lag other than the family's, settle as a run judges them.

A run judges a step settled from the last row at which the rotor lies outside a band of
:data:`~heliostep.results.figures.steps.SETTLING_BAND` of a step increment around its rest
(:func:`~heliostep.results.figures.steps.step_outcome`). That time jumps with the panel's angle, by a
half period of the ring, wherever one of the ring's swings shrinks below the band. The swings themselves
change smoothly with the angle, so a family keeps each swing (a lobe: the rows between two crossings of
the rest) with its height, the time the rotor comes back into the band after it and the rate at which it
does, and a case's settling is the last swing that still leaves the band, the swings interpolated between
the family's two angles around its step (the heights geometrically, as a damped ring's shrink).
"""

from __future__ import annotations

import numpy as np

__all__ = ["LOBES", "lobes", "settling_figures", "settling_times"]

#: The swings of a step's ring a family keeps: a step whose last kept swing still leaves the band is not
#: settled (a lightly damped ring swings some tens of times before it stays within).
LOBES = 64


def lobes(time: np.ndarray, deviation: np.ndarray, t_step: float) -> np.ndarray:
    """The first :data:`LOBES` swings of a step's ring, shape (LOBES, 4): height of the swing [bands]; the
    time from the step until the rotor is back within the band [s] (the swing's peak where it stays within);
    the rate at which the deviation falls through the band there [bands/s]; the swing's side (-1, +1).

    ``time`` [s] and ``deviation`` [bands] are the rows from the step on: the rotor minus its rest, in the
    settling band's width. Missing swings are zeros."""
    side = np.where(deviation < 0.0, -1.0, 1.0)
    starts = np.flatnonzero(np.diff(side, prepend=0.0))
    ends = np.append(starts[1:], len(time))
    size = np.abs(deviation)
    kept = np.zeros((LOBES, 4))
    for k, (i, j) in enumerate(zip(starts[:LOBES], ends[:LOBES], strict=False)):
        peak = i + int(np.argmax(size[i:j]))
        kept[k, 0], kept[k, 3] = size[peak], side[i]
        outside = np.flatnonzero(size[peak:j] > 1.0)
        last = peak + int(outside[-1]) if len(outside) else -1
        if last < 0 or last + 1 >= len(time):  # within the band, or still out at the window's end
            kept[k, 1] = time[peak] - t_step if last < 0 else np.inf
            continue
        d0, d1 = size[last] - 1.0, size[last + 1] - 1.0  # as the run interpolates its crossing
        fraction = d0 / (d0 - d1) if d0 != d1 else 1.0
        span = time[last + 1] - time[last]
        kept[k, 1] = time[last] + fraction * span - t_step
        kept[k, 2] = (d0 - d1) / span if span > 0 else 0.0
    return kept


def settling_times(below: np.ndarray, above: np.ndarray, weight: np.ndarray, shift: np.ndarray) -> np.ndarray:
    """Each step's settling time [s] from the swings of the family's transients at the angles below and
    above it (``below``, ``above``: shape (steps, LOBES, 4), as :func:`lobes`), interpolated by ``weight``
    (0 at the angle below, 1 above), with the rest moved by ``shift`` [bands] (the run judges every step
    about the lag held at its first row; a step held at another load lags by other than that): the
    swings on the side of the shift shrink by it and come back into the band sooner, to first order."""
    w = weight[:, None]
    low, high = below[..., 0], above[..., 0]
    both = (low > 0.0) & (high > 0.0)
    # the heights geometric, as a ring decays; linear where a swing is missing at one of the two angles
    geometric = np.exp((1.0 - w) * np.log(np.where(both, low, 1.0)) + w * np.log(np.where(both, high, 1.0)))
    height = np.where(both, geometric, (1.0 - w) * low + w * high)
    back = (1.0 - w) * below[..., 1] + w * above[..., 1]
    rate = (1.0 - w) * below[..., 2] + w * above[..., 2]
    side = np.where(w < 0.5, below[..., 3], above[..., 3])
    moved = side * shift[:, None]
    height = height - moved
    with np.errstate(divide="ignore", invalid="ignore"):
        back = np.where(rate > 0.0, back - moved / rate, back)
    out = height > 1.0
    last = LOBES - 1 - np.argmax(out[:, ::-1], axis=1)
    settling = np.where(out.any(axis=1), back[np.arange(len(back)), last], 0.0)
    return np.where(out[:, -1], np.inf, settling)


def settling_figures(
    swings: np.ndarray, angles: np.ndarray, angle: np.ndarray, steps, lag: np.ndarray, rests: np.ndarray
) -> dict:
    """``settling_time_max_s``, ``settling_time_mean_s`` and ``settling_not_settled`` (a run's
    ``settling_time_s`` as a sweep's table gives it) of a case's steps at panel angles ``angle`` [rad]
    (``steps``: each step's direction and phase), from a family's ``swings`` (shape (angles, 2, cycle, LOBES,
    4)) at its ``angles`` [rad] around each, about the lag held before the first step (``lag``: each
    step's own [bands]); a step not settled within its rest before the next step or the window's end
    (``rests`` [s]) is not settled."""
    direction, phase = steps
    below = np.clip(np.searchsorted(angles, angle) - 1, 0, len(angles) - 2)
    weight = (angle - angles[below]) / np.diff(angles)[below]
    side = (direction > 0).astype(int)
    settling = settling_times(swings[below, side, phase], swings[below + 1, side, phase], weight, lag - lag[0])
    settled = settling[settling <= rests]
    return {
        "settling_time_max_s": float(settled.max()) if len(settled) else None,
        "settling_time_mean_s": float(settled.mean()) if len(settled) else None,
        "settling_not_settled": int(len(settling) - len(settled)),
    }
