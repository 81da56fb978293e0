"""The receiver's image of an attitude that is a function of the sun alone, from the sun grid.

The ideal attitude and the shared one (:mod:`heliostep.results.light.on_tube`) depend on the sun alone, and
the sun moves 0.25 deg/min: their image on the receiver (the intercept and the central ray's misses,
:func:`heliostep.results.light.mirror_power.receiver_image`, 64 normal-CDF evaluations a row and the
costly part of the light) changes over hours. It is computed at the sun grid's points
(``light.SUN_GRID_S`` apart) and interpolated linearly onto the rows; linear interpolation over dt
errs by at most (dt^2 / 8) |gamma''| (3e-8 and 6e-8 of the intercept an hour after sunrise in January,
bare tube and secondary concentrator), and below 1e-6 of an energy
(``tests/results/light/test_light.py::test_the_sun_alone_attitudes_image_from_the_sun_grid_is_the_rows_own_within_its_curvature``:
against the image of the exact attitude at every row).
Over a grid interval with a point below the horizon the grid's attitude is not the rows' (the field's
sharing is 0 there): those rows take their own image. The cosine, the receiver's shadow (kinked
where its edge crosses the mirror) and the end fraction stay the rows' own
(:func:`heliostep.results.light.mirror_power.attitude_light`).
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
