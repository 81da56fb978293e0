"""The receiver's image of an attitude that is a function of the sun alone, from the sun grid.

Details: docs/light.md, ``heliostep.results.light.sun_grid_image``.
"""

from __future__ import annotations

import numpy as np

from heliostep.results.light.mirror_power import IMAGE_KEYS, receiver_image

__all__ = ["interpolated_image"]


def interpolated_image(
    points: dict, grid_attitude: tuple, rows: tuple, distance: float, tube_height: float, conf
) -> dict:
    """The receiver's image of a sun-alone attitude at the rows.

    Parameters
    ----------
    points : dict
        The sun grid (``light.sun_grid``): ``time`` [s], ``sun`` (3, m) [-], ``elevation`` [deg].
    grid_attitude : tuple
        ``(primary, secondary)``, the attitude at the grid's points: arrays (m,) [rad].
    rows : tuple
        ``(seconds, sun, primary, secondary)`` at the rows: times [s] (n,), the sun's unit vector
        (3, n) and the attitude [rad] (n,).
    distance, tube_height : float  [m]
    conf : heliostep.scenario.OpticsConfig

    Returns
    -------
    dict of arrays (n,)
        :data:`heliostep.results.light.mirror_power.IMAGE_KEYS`: interpolated between two grid points with
        the sun up at both, the rows' own elsewhere.
    """
    seconds, sun, primary, secondary = rows
    grid_s = points["time"]
    grid_primary, grid_secondary = grid_attitude
    at_points = receiver_image(points["sun"], grid_primary, grid_secondary, distance, tube_height, conf)
    image = {key: np.interp(seconds, grid_s, at_points[key]) for key in IMAGE_KEYS}
    up = points["elevation"] > 0.0
    # the grid point at or before each row (the grid brackets the rows with two points or more)
    before = np.clip(np.searchsorted(grid_s, seconds, side="right") - 1, 0, len(grid_s) - 2)
    own = ~(up[before] & up[before + 1])
    if own.any():
        exact = receiver_image(sun[:, own], primary[own], secondary[own], distance, tube_height, conf)
        for key in IMAGE_KEYS:
            image[key][own] = exact[key]
    return image
