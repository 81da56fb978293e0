"""Shading and blocking of a plant's rows at their tracking attitudes: single-axis rows and two-axis end mirrors.

The rows' normals from the tracking laws ([paper], eq. 1 for single-axis rows; eqs. 3-6 for the
two-axis end mirrors), their neighbours' shading and blocking (:func:`heliostep.solar.shading.row_losses`)
and the receiver's own shadow (:mod:`heliostep.solar.receiver_shadow`), per instant, for
:mod:`heliostep.solar.endloss`; and the same over a year's grid with the costly two-axis polygons at a
coarser step, interpolated (:func:`interpolated_losses`).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from heliostep.solar.checks import as_float_array
from heliostep.solar.field import PANEL_LENGTH
from heliostep.solar.receiver_shadow import receiver_shadow_fraction
from heliostep.solar.shading import coarse_instants, interpolated, row_losses
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


#: Instants of a grid whose losses are computed together (whole days, at least one): bounds the memory of
#: the two-axis footprints (instants by rows by neighbours by corners), gigabytes for a year at once.
BLOCK_INSTANTS = 2048


def interpolated_losses(
    elevation,
    azimuth,
    labels,
    every,
    distances,
    tube_height,
    width,
    length,
    plant_azimuth,
    receiver_width,
    *,
    progress: Callable[[int], object] | None = None,
):
    """:func:`shading_losses`: the two-axis neighbours' at every ``every``-th instant with the sun up (and each
    day's first and last such instant), interpolated linearly in the instants' index between; the
    single-axis rows and the receiver's shadow at every instant; 1 while the sun is down.

    Computed over blocks of whole days (``labels``: a day label per instant, each day's instants together)
    of about :data:`BLOCK_INSTANTS` instants; ``progress(days)`` is called after each block with the
    number of days it held."""
    geometry = (distances, tube_height, width, length, plant_azimuth, receiver_width)
    elevation, azimuth = np.atleast_1d(as_float_array(elevation)), np.atleast_1d(as_float_array(azimuth))
    labels = np.asarray(labels)
    up = np.flatnonzero(elevation > 0.0)
    coarse = coarse_instants(up, every, labels) if up.size else up  # over the whole grid: the step's phase kept
    parts = []
    for start, stop, days in _day_blocks(labels, BLOCK_INSTANTS):
        out = shading_losses(elevation[start:stop], azimuth[start:stop], *geometry, two_axis_neighbours=False)
        lit = up[(up >= start) & (up < stop)]
        if lit.size:  # each day's first and last lit instants are coarse: no interpolation crosses a block
            sampled = coarse[(coarse >= start) & (coarse < stop)]
            neighbours = shading_losses(elevation[sampled], azimuth[sampled], *geometry)["two_axis_neighbours"]
            at = lit - start
            out["two_axis_neighbours"][at] = interpolated(lit, sampled, neighbours)
            out["two_axis"][at] = 1.0 - (1.0 - out["two_axis_neighbours"][at]) * (1.0 - out["two_axis_receiver"][at])
        parts.append(out)
        if progress is not None:
            progress(days)
    return {key: np.concatenate([part[key] for part in parts]) for key in parts[0]}


def _day_blocks(labels: np.ndarray, size: int) -> list[tuple[int, int, int]]:
    """(start, stop, days): consecutive runs of whole days of ``labels`` (a label per instant), each of at
    most ``size`` instants unless one day alone has more."""
    turns = np.flatnonzero(np.r_[True, labels[1:] != labels[:-1]]).tolist() + [labels.size]
    blocks, start, days = [], 0, 0
    for begin, end in zip(turns[:-1], turns[1:]):
        if days and end - start > size:
            blocks.append((start, begin, days))
            start, days = begin, 0
        days += 1
    blocks.append((start, labels.size, days))
    return blocks
