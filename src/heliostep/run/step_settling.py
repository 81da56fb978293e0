"""A step's settling time as a family keeps it: the lobes of its ring, so that a case's steps between the
family's angles, and held at a load's lag other than the family's, settle as a run judges them.

A run judges a step settled from the last row at which the rotor lies outside a band of
:data:`~heliostep.results.figures.steps.SETTLING_BAND` of a step increment around its rest
(:func:`~heliostep.results.figures.steps.step_outcome`). That time jumps with the panel's angle, by a
half period of the ring, wherever one of the ring's swings shrinks below the band. The swings themselves
change smoothly with the angle, so a family keeps each swing (a lobe: the rows between two crossings of
the rest) with its height, the time the rotor comes back into the band after it and the rate at which it
does, and a case's settling is the last swing that still leaves the band, each swing interpolated
between the family's two angles around its step.
"""

from __future__ import annotations

import numpy as np

__all__ = ["LOBES", "lobes", "settling_figures", "settling_times", "swings_at"]

#: The swings of a step's ring a family keeps: a step whose last kept swing still leaves the band is not
#: settled (a lightly damped ring swings some tens of times before it stays within).
LOBES = 64


def lobes(time: np.ndarray, deviation: np.ndarray, t_step: float) -> np.ndarray:
    """The first :data:`LOBES` swings of a step's ring, shape (LOBES, 4): the height of the swing [bands]; the
    time from the step until the rotor is back within the band [s] (the swing's peak where it stays within,
    the window's end where it is still out); the rate at which the deviation falls through the band there
    [bands/s]; the swing's side (-1, +1).

    ``time`` [s] and ``deviation`` [bands] are the rows from the step on: the rotor minus its rest, in the
    settling band's width. After the first swing within the band the heights go on losing what the last
    swing lost (below none where the ring has stopped, as under dry friction), and swings after the ring has
    stopped follow the last in time: a ring that stops there and its neighbour's that swings once more
    interpolate as the swings it would have made."""
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
            kept[k, 1] = time[peak if last < 0 else -1] - t_step
            continue
        d0, d1 = size[last] - 1.0, size[last + 1] - 1.0  # as the run interpolates its crossing
        fraction = d0 / (d0 - d1) if d0 != d1 else 1.0
        span = time[last + 1] - time[last]
        kept[k, 1] = time[last] + fraction * span - t_step
        kept[k, 2] = (d0 - d1) / span if span > 0 else 0.0
    found = min(len(starts), LOBES)
    if 2 <= found < LOBES:  # the ring has stopped (dry friction): the swings after it follow the last in time
        later = np.arange(1, LOBES - found + 1)
        kept[found:, 1] = kept[found - 1, 1] + later * np.median(np.diff(kept[:found, 1]))
        kept[found:, 2] = kept[found - 1, 2]
        kept[found:, 3] = kept[found - 1, 3] * (-1.0) ** later
    inside = np.flatnonzero(kept[1:found, 0] <= 1.0) + 1
    if len(inside):  # after the first swing within the band, the heights the last two swings' loss goes on to
        first = int(inside[0])
        after = np.arange(1, LOBES - first)
        kept[first + 1 :, 0] = kept[first, 0] - after * (kept[first - 1, 0] - kept[first, 0])
    return kept


def swings_at(table: np.ndarray, grid: np.ndarray, x: np.ndarray) -> np.ndarray:
    """The swings at each of ``x`` from the swings ``table`` (shape (points, LOBES, 4), as :func:`lobes`) at
    the points ``grid``: each swing's height, time back and rate linear between the two points around each
    (exact where the ring loses the same height each swing, as the panel's dry friction makes it; a ring
    that decays by a factor each swing, viscous, may have its last swing out of the band misplaced by one
    near a jump), its side the nearer point's. Shape (len(x), LOBES, 4)."""
    below = np.clip(np.searchsorted(grid, x) - 1, 0, len(grid) - 2)
    weight = ((x - grid[below]) / np.diff(grid)[below])[:, None, None]
    values = (1.0 - weight) * table[below, :, :3] + weight * table[below + 1, :, :3]
    nearest = np.clip(np.rint(np.interp(x, grid, np.arange(len(grid)))).astype(int), 0, len(grid) - 1)
    return np.concatenate([values, table[nearest][..., 3:]], axis=-1)


def settling_times(swings: np.ndarray, shift: np.ndarray) -> np.ndarray:
    """Each step's settling time [s] from its ``swings`` (shape (steps, LOBES, 4), :func:`swings_at`), with
    the rest moved by ``shift`` [bands] (the run judges every step about the lag held at its first row; a
    step held at another load lags by other than that): the swings on the side of the shift shrink by it
    and come back into the band sooner, to first order. A step whose last swing given still leaves the band
    has not settled (inf)."""
    height, back, rate, side = (swings[..., k] for k in range(4))
    moved = side * shift[:, None]
    height = height - moved
    with np.errstate(divide="ignore", invalid="ignore"):
        back = np.where(rate > 0.0, back - moved / rate, back)
    out = height > 1.0
    last = out.shape[1] - 1 - np.argmax(out[:, ::-1], axis=1)
    settling = np.where(out.any(axis=1), back[np.arange(len(back)), last], 0.0)
    return np.where(out[:, -1], np.inf, settling)


def settling_figures(
    swings: np.ndarray, angles: np.ndarray, angle: np.ndarray, steps, lag: np.ndarray, rests: np.ndarray
) -> dict:
    """``settling_time_max_s``, ``settling_time_mean_s`` and ``settling_not_settled`` (a run's
    ``settling_time_s`` as a sweep's table gives it) of a case's steps at panel angles ``angle`` [rad]
    (``steps``: each step's direction and phase), from a family's ``swings`` (shape (angles, 2, cycle, LOBES,
    4)) at its ``angles`` [rad], about the lag held before the first step (``lag``: each step's own
    [bands]); a step not settled within its rest before the next step or the window's end (``rests`` [s]) is
    not settled."""
    direction, phase = steps
    side, shift = (direction > 0).astype(int), lag - lag[0]
    reach = np.flatnonzero((swings[..., 0] > 0.9 - np.abs(shift).max(initial=0.0)).any(axis=(0, 1, 2)))
    count = min(LOBES, int(reach[-1]) + 2) if len(reach) else 1  # the swings that may leave the band, and one
    swings = swings[..., :count, :]
    at = np.zeros((len(angle), count, 4))
    for d, p in set(zip(side.tolist(), phase.tolist())):
        chosen = (side == d) & (phase == p)
        at[chosen] = swings_at(swings[:, d, p], angles, angle[chosen])
    settling = settling_times(at, shift)
    settled = settling[settling <= rests]
    return {
        "settling_time_max_s": float(settled.max()) if len(settled) else None,
        "settling_time_mean_s": float(settled.mean()) if len(settled) else None,
        "settling_not_settled": int(len(settling) - len(settled)),
    }
