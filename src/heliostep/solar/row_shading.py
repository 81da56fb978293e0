"""Shading and blocking of a plant's rows at their tracking attitudes: single-axis rows and two-axis end mirrors.

The rows' normals from the tracking laws ([paper], eq. 1 for single-axis rows; eqs. 3-6 for the
two-axis end mirrors), their neighbours' shading and blocking (:func:`heliostep.solar.shading.row_losses`)
and the receiver's own shadow (:mod:`heliostep.solar.receiver_shadow`), per instant, for
:mod:`heliostep.solar.endloss`; and the same over a year's grid with the costly two-axis polygons at a
coarser step, interpolated (:func:`interpolated_losses`).
"""

from __future__ import annotations

import numpy as np

from heliostep.solar.checks import as_float_array
from heliostep.solar.field import PANEL_LENGTH
from heliostep.solar.receiver_shadow import receiver_shadow_fraction
from heliostep.solar.shading import interpolated_at_coarse_instants, row_losses
from heliostep.solar.sun import sun_vector
from heliostep.solar.tracking import single_axis_tilt, two_axis_normal

__all__ = ["interpolated_losses", "shading_losses", "tracking_normals"]


def shading_losses(
    elevation,
    azimuth,
    mirror_distances,
    tube_height,
    mirror_width,
    mirror_length=PANEL_LENGTH,
    plant_azimuth=0.0,
    receiver_width: float | None = None,
    two_axis_neighbours: bool = True,
) -> dict:
    """Share of each row's light lost to shading and blocking, single-axis rows and two-axis end mirrors.

    Parameters
    ----------
    elevation, azimuth : array-like, shape (T,)  [deg]
    mirror_distances : array-like, shape (N,)  [m]
    tube_height, mirror_width : float  [m]
    mirror_length : float, default :data:`heliostep.solar.field.PANEL_LENGTH`  [m]
        Of each two-axis mirror, contiguous along the row.
    plant_azimuth : float, default 0  [deg]
    receiver_width : float, optional  [m]
        The receiver's width across, its own shadow (:mod:`heliostep.solar.receiver_shadow`): united
        exactly with the neighbours' on the single-axis rows (all bands along the row); on the two-axis
        mirrors combined with theirs as independent, 1 - (1 - lost) (1 - s_r) (its band runs along the
        mirror, the along-row shadows across it). None: no receiver shadow.
    two_axis_neighbours : bool, default True
        False: skip the two-axis neighbours' polygons (the costly part; ``two_axis_neighbours`` is then 0).

    Returns
    -------
    dict of numpy.ndarray, shape (T, N)  [-]
        ``single``, ``two_axis``: :func:`heliostep.solar.shading.row_losses`'s ``lost`` with the rows'
        tracking normals ([paper], eq. 1; eqs. 3-6), the receiver's shadow included; their parts
        ``two_axis_neighbours`` and ``two_axis_receiver``; 1 while the sun is down (0 for the parts).
    """
    elevation, azimuth = np.atleast_1d(as_float_array(elevation)), np.atleast_1d(as_float_array(azimuth))
    distances = np.atleast_1d(as_float_array(mirror_distances)).ravel()
    up = elevation > 0.0
    single, two = np.ones((elevation.size, distances.size)), np.ones((elevation.size, distances.size))
    neighbours, own = np.zeros_like(two), np.zeros_like(two)
    receiver = None if not receiver_width else (tube_height, receiver_width)
    if up.any():
        e, a = elevation[up, None], azimuth[up, None]
        sun, normal_single, normal_two = tracking_normals(e, a, distances, tube_height, plant_azimuth)
        single[up] = row_losses(sun, normal_single, distances, mirror_width, only_lost=True, receiver=receiver)["lost"]
        if two_axis_neighbours:
            neighbours[up] = row_losses(sun, normal_two, distances, mirror_width, mirror_length, only_lost=True)["lost"]
        if receiver is not None:
            mirror = (receiver_width, mirror_width, mirror_length)
            own[up] = receiver_shadow_fraction(sun[:, None, :], normal_two, distances[None, :], tube_height, *mirror)
        two[up] = 1.0 - (1.0 - neighbours[up]) * (1.0 - own[up])
    return {"single": single, "two_axis": two, "two_axis_neighbours": neighbours, "two_axis_receiver": own}


def tracking_normals(elevation, azimuth, mirror_distances, tube_height, plant_azimuth=0.0):
    """The sun (T, 3) and the rows' tracking normals [-] (T, N, 3): single-axis ([paper], eq. 1) and two-axis
    ([paper], eqs. 3-6), from the sun's ``elevation``, ``azimuth`` [deg] (T, 1) and the rows' distances [m]."""
    distances = np.atleast_1d(as_float_array(mirror_distances)).ravel()
    sun = np.stack(sun_vector(elevation[:, 0], azimuth[:, 0], plant_azimuth), axis=-1)
    beta = as_float_array(single_axis_tilt(elevation, azimuth, distances[None, :], tube_height, plant_azimuth))
    normal_single = np.stack([np.cos(beta), np.zeros_like(beta), np.sin(beta)], axis=-1)  # [paper], eq. 1
    sun_x, sun_y, sun_z = (c[:, None] for c in sun.T)
    normal_two = np.stack(
        np.broadcast_arrays(*two_axis_normal(sun_x, sun_y, sun_z, distances[None, :], tube_height)), axis=-1
    )  # [paper], eqs. 3-6
    return sun, normal_single, normal_two


def interpolated_losses(
    elevation, azimuth, labels, every, distances, tube_height, width, length, plant_azimuth, receiver_width
):
    """:func:`shading_losses`: the two-axis neighbours' at every ``every``-th instant with the sun up (and each
    day's first and last such instant), interpolated linearly in the instants' index between; the
    single-axis rows and the receiver's shadow at every instant; 1 while the sun is down."""
    geometry = (distances, tube_height, width, length, plant_azimuth, receiver_width)
    out = shading_losses(elevation, azimuth, *geometry, two_axis_neighbours=False)
    up = np.flatnonzero(elevation > 0.0)
    if up.size == 0:
        return out
    out["two_axis_neighbours"][up] = interpolated_at_coarse_instants(
        up,
        every,
        lambda coarse: shading_losses(elevation[coarse], azimuth[coarse], *geometry)["two_axis_neighbours"],
        labels,
    )
    out["two_axis"][up] = 1.0 - (1.0 - out["two_axis_neighbours"][up]) * (1.0 - out["two_axis_receiver"][up])
    return out
