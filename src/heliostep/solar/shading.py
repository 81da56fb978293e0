"""Shading and blocking between neighbouring mirrors of a linear Fresnel field.

A neighbour's footprint projected along the sun (shading) or the reflected ray (blocking) onto a
mirror's plane; exact in 2-D for single-axis rows, parallelograms unioned by slabs for two-axis
end mirrors.

Details: docs/light.md, ``heliostep.solar.shading``.
"""

from __future__ import annotations

import numpy as np

from heliostep.errors import InputError
from heliostep.solar.checks import as_float_array, check_positive
from heliostep.solar.optics import mirror_axes
from heliostep.solar.receiver_shadow import receiver_shadow_band

__all__ = ["coarse_instants", "interpolated", "interpolated_at_coarse_instants", "row_losses"]


def reflected_direction(sun, normal):
    """Direction of the light a flat mirror reflects, r = 2 (S . n) n - S (law of reflection).

    Parameters
    ----------
    sun, normal : array-like, shape (..., 3)  [-]
        Unit vectors toward the sun and of the mirror's normal.

    Returns
    -------
    numpy.ndarray, shape (..., 3)  [-]
    """
    sun, normal = as_float_array(sun), as_float_array(normal)
    return 2.0 * np.sum(sun * normal, axis=-1, keepdims=True) * normal - sun  # law of reflection


def interval_union_length(low, high, axis: int = -1):
    """Total length of the union of intervals [low, high] (empty where high <= low).

    Parameters
    ----------
    low, high : array-like  [m]
        Interval ends; ``axis`` runs over the intervals.

    Returns
    -------
    numpy.ndarray  [m]
        Sorted by their start, each interval adds what reaches past the farthest end before it.
    """
    low, high = np.broadcast_arrays(as_float_array(low), as_float_array(high))
    low, high = np.moveaxis(low, axis, -1), np.moveaxis(high, axis, -1)
    high = np.where(high > low, high, -np.inf)  # empty intervals add nothing
    order = np.argsort(low, axis=-1)
    low, high = np.take_along_axis(low, order, -1), np.take_along_axis(high, order, -1)
    reach = np.maximum.accumulate(high, axis=-1)
    before = np.concatenate([np.full(reach.shape[:-1] + (1,), -np.inf), reach[..., :-1]], axis=-1)
    added = high - np.maximum(low, before)
    return np.sum(np.where(np.isfinite(added) & (added > 0), added, 0.0), axis=-1)


def _across_intervals(direction, normals, mirror_distances, width: float) -> tuple[np.ndarray, np.ndarray]:
    """The neighbours' footprints on each mirror along e_u [m], (T, N_i, N_j), empty (0, 0) where none."""
    normal, e_u, _ = mirror_axes(*np.moveaxis(as_float_array(normals), -1, 0))
    d = np.atleast_1d(as_float_array(mirror_distances)).ravel()
    if normal.ndim != 3 or normal.shape[1] != d.size:
        raise InputError(f"normals: expected shape (instants, {d.size}, 3), got {normal.shape}")
    D = np.broadcast_to(_per_mirror(direction, normal.shape), normal.shape)[:, :, None, :]  # (T, N_i, 1, 3)
    n_i, u_i = normal[:, :, None, :], e_u[:, :, None, :]
    offset = np.zeros(normal.shape[:1] + (d.size, d.size, 3))
    offset[..., 0] = d[None, None, :] - d[None, :, None]  # neighbour j's pivot from mirror i's
    ends = [offset + sign * 0.5 * width * e_u[:, None, :, :] for sign in (-1.0, 1.0)]  # its long edges
    with np.errstate(invalid="ignore", divide="ignore"):
        dn = np.sum(D * n_i, axis=-1)
        lam = [np.sum(p * n_i, axis=-1) / dn for p in ends]  # lambda = (P - C).n / (D.n)
        u = [np.sum((p - lm[..., None] * D) * u_i, axis=-1) for p, lm in zip(ends, lam)]  # footprint along e_u
        low = np.clip(np.minimum(u[0], u[1]), -width / 2, width / 2)
        high = np.clip(np.maximum(u[0], u[1]), -width / 2, width / 2)
        t_mid = ((low + high) / 2 - u[0]) / (u[1] - u[0])  # where on the neighbour the overlap's middle lies
        lam_mid = lam[0] + t_mid * (lam[1] - lam[0])
    ahead = (lam_mid > 0) & np.isfinite(lam_mid) & ~np.eye(d.size, dtype=bool)[None]
    return np.where(ahead, low, 0.0), np.where(ahead, high, 0.0)


def _per_mirror(direction, shape) -> np.ndarray:
    """``direction`` (T, 3) or (T, N, 3) as (T, N, 3), unit."""
    direction = as_float_array(direction)
    if direction.ndim == 2:
        direction = direction[:, None, :]
    if direction.shape[-1] != 3 or direction.ndim != 3:
        raise InputError(f"direction: expected shape (instants, 3) or {shape}, got {direction.shape}")
    return direction / np.linalg.norm(direction, axis=-1, keepdims=True)


def footprints(direction, normals, mirror_distances, mirror_width, mirror_length, pitch, reach: int = 1):
    """Footprints on each two-axis mirror of its neighbours in the section, in its (e_u, e_v) frame.

    Parameters
    ----------
    direction : array-like, shape (T, 3) or (T, N, 3)  [-]
        Toward the sun (shading) or along the reflected ray (blocking).
    normals : array-like, shape (T, N, 3)  [-]
        One normal per row (every mirror of a row has the same: same d, same sun).
    mirror_distances : array-like, shape (N,)  [m]
    mirror_width, mirror_length, pitch : float  [m]
        w, l and the centre-to-centre spacing p along the row.
    reach : int, default 1
        Every other row is taken; along each row, the mirror whose footprint's centre comes closest
        to the mirror's and ``reach`` on each side of it (a row's mirrors' footprints are translates
        of one another by one pitch's projection, delta, so the ones meeting the mirror are these).

    Returns
    -------
    u, v : numpy.ndarray, shape (T, N, K, 8)  [m]
        The corners, in order, of each neighbour's footprint: its rectangle projected along
        ``direction`` onto the mirror's plane, a parallelogram (an affine image of a rectangle),
        exact, of the part of it ahead of the mirror (lambda > 0; up to 8 corners, some repeated);
        NaN for the mirror itself or a neighbour none of which is ahead; K = N (2 ``reach`` + 1).
    """
    width = check_positive(mirror_width, "mirror_width", "m")
    length = check_positive(mirror_length, "mirror_length", "m")
    pitch = check_positive(pitch, "pitch", "m")
    normal, e_u, e_v = mirror_axes(*np.moveaxis(as_float_array(normals), -1, 0))
    d = np.atleast_1d(as_float_array(mirror_distances)).ravel()
    D = np.broadcast_to(_per_mirror(direction, normal.shape), normal.shape)
    offset, j_k, exists = _neighbours(D, normal, e_u, e_v, d, pitch, reach)
    e_u_j = np.take_along_axis(e_u[:, None, :, :], j_k[..., None], axis=2)  # (T, N, K, 3)
    e_v_j = np.take_along_axis(e_v[:, None, :, :], j_k[..., None], axis=2)
    n_i, u_i, v_i, D_i = (x[:, :, None, None, :] for x in (normal, e_u, e_v, D))
    signs = np.array([(-1, -1), (1, -1), (1, 1), (-1, 1)], dtype=float) * 0.5
    corners = (
        offset[:, :, :, None, :]
        + signs[:, 0, None] * width * e_u_j[:, :, :, None, :]
        + signs[:, 1, None] * length * e_v_j[:, :, :, None, :]
    )  # (T, N, K, 4, 3)
    with np.errstate(invalid="ignore", divide="ignore"):
        dn = np.sum(D_i * n_i, axis=-1)
        lam = np.sum(corners * n_i, axis=-1) / dn  # lambda = (P - C).n / (D.n)
        at = corners - lam[..., None] * D_i
        u, v = np.sum(at * u_i, axis=-1), np.sum(at * v_i, axis=-1)
    u, v = _ahead_part(u, v, lam)
    keep = exists[..., None]
    return np.where(keep, u, np.nan), np.where(keep, v, np.nan)


def _neighbours(D, normal, e_u, e_v, d, pitch: float, reach: int):
    """The neighbours :func:`footprints` projects: offsets of their centres from each mirror's [m]
    (T, N, K, 3), their rows (T, N, K) and whether they exist (not the mirror itself)."""
    j = np.broadcast_to(np.arange(d.size), (d.size, d.size))  # (N, R): every row for each mirror, its own too
    n_t, u_t, v_t, D_t = (x[:, :, None, :] for x in (normal, e_u, e_v, D))
    with np.errstate(invalid="ignore", divide="ignore"):
        dn_t = np.sum(D_t * n_t, axis=-1)  # (T, N, 1)
        # row j's mirror beside mirror i (same y): its centre's footprint; the next one along the row moves
        # it by delta = (0, p, 0) - lambda D, lambda = p n_y / (D.n), the same for every row (one pitch)
        across = np.zeros(j.shape + (3,))
        across[..., 0] = d[j] - d[:, None]
        centre = across[None] - (np.sum(across[None] * n_t, axis=-1) / dn_t)[..., None] * D_t
        step = np.array([0.0, pitch, 0.0]) - (pitch * normal[..., 1:2] / dn_t)[..., None] * D_t  # (T, N, 1, 3)
        c_uv = np.stack([np.sum(centre * u_t, -1), np.sum(centre * v_t, -1)], -1)
        s_uv = np.stack([np.sum(step * u_t, -1), np.sum(step * v_t, -1)], -1)
        nearest = np.rint(-np.sum(c_uv * s_uv, -1) / np.sum(s_uv * s_uv, -1))  # the m that brings it closest
    nearest = np.where(np.isfinite(nearest), nearest, 0.0)
    m = nearest[..., None] + np.arange(-reach, reach + 1)  # (T, N, R, M)
    shape = m.shape[:2] + (m.shape[2] * m.shape[3],)
    m = m.reshape(shape)
    j_k = np.broadcast_to(np.repeat(j, 2 * reach + 1, axis=1)[None], shape)
    own_row = np.repeat(j == np.arange(d.size)[:, None], 2 * reach + 1, axis=1)[None]
    exists = ~(own_row & (m == 0))  # not the mirror itself
    offset = np.zeros(shape + (3,))
    offset[..., 0] = d[j_k] - d[None, :, None]
    offset[..., 1] = m * pitch
    return offset, j_k, exists


def _ahead_part(u, v, lam) -> tuple[np.ndarray, np.ndarray]:
    """The footprint of the part of each neighbour ahead of the mirror (lambda > 0), up to 8 corners.

    The neighbour's corners' footprints (u, v) [m] and their lambda, (..., 4); one clip of the polygon
    by the half-plane lambda > 0 (Sutherland-Hodgman; lambda is affine over the neighbour's plane). Slots
    of no corner repeat the previous corner (a zero-length edge), NaN if no part is ahead."""
    nxt = [np.roll(x, -1, axis=-1) for x in (u, v, lam)]
    with np.errstate(invalid="ignore", divide="ignore"):
        t = lam / (lam - nxt[2])  # where an edge crosses lambda = 0
        crossing = (lam > 0) != (nxt[2] > 0)
        slots_u = np.stack([np.where(lam > 0, u, np.nan), np.where(crossing, u + t * (nxt[0] - u), np.nan)], -1)
        slots_v = np.stack([np.where(lam > 0, v, np.nan), np.where(crossing, v + t * (nxt[1] - v), np.nan)], -1)
    slots_u, slots_v = slots_u.reshape(u.shape[:-1] + (8,)), slots_v.reshape(v.shape[:-1] + (8,))
    empty = np.isnan(slots_u)
    for _ in range(8):  # fill the empty slots with the previous corner, round the polygon
        slots_u = np.where(empty, np.roll(slots_u, 1, axis=-1), slots_u)
        slots_v = np.where(empty, np.roll(slots_v, 1, axis=-1), slots_v)
        still = np.isnan(slots_u)
        if np.array_equal(still, empty):  # nothing filled: nothing will be (all-empty polygons stay so)
            break
        empty = still
    return slots_u, slots_v


#: Each slab between corners is cut in this many for the midpoint rule (exact where no two footprints'
#: edges cross inside a slab; where they do, the error falls as 1 / SUB_SLABS^2): 2 keeps it within
#: 0.01 of the ray tracer in ``tests/solar/test_shading.py``.
SUB_SLABS = 2


def covered_fraction(u, v, mirror_width, mirror_length):
    """Fraction of a w x l mirror covered by the union of convex footprints (corners in order).

    In slabs between all corners' u (and the u where an edge meets the mirror's ends v = +-l/2), each
    footprint spans one v-interval (where a line of constant u crosses its edges), taken at the slab's
    middle; their union (:func:`interval_union_length`) times the slab's width, summed. Exact when no
    two footprints' edges cross inside a slab (the union is then linear in u across it); else the
    midpoint rule on a piecewise-linear length.

    Parameters
    ----------
    u, v : array-like, shape (..., K, C)  [m]
        Corners of K convex footprints (NaN: none) in the mirror's frame, centred on it.
    mirror_width, mirror_length : float  [m]
    """
    u, v = as_float_array(u), as_float_array(v)
    half_w, half_l = mirror_width / 2, mirror_length / 2
    lead, (k, c) = u.shape[:-2], u.shape[-2:]
    u, v = u.reshape((-1, k, c)), v.reshape((-1, k, c))
    finite = np.isfinite(u) & np.isfinite(v)
    low_u, high_u = np.where(finite, u, np.inf).min(-1), np.where(finite, u, -np.inf).max(-1)
    low_v, high_v = np.where(finite, v, np.inf).min(-1), np.where(finite, v, -np.inf).max(-1)
    meets = (low_u < half_w) & (high_u > -half_w) & (low_v < half_l) & (high_v > -half_l)  # bounding boxes meet
    count = meets.sum(-1)
    by_count = np.argsort(count, kind="stable")  # mirrors with as many footprints together: each batch its own K
    area = np.zeros(u.shape[0])
    start = 0
    while start < u.shape[0]:
        many = max(int(count[by_count[min(start + 255, u.shape[0] - 1)]]), 1)
        chunk = max(1, min(256, int(2e6 // (many**2 * c * c * SUB_SLABS))))
        rows = by_count[start : start + chunk]
        first = np.argsort(~meets[rows], axis=-1, kind="stable")[:, :many]
        keep = np.take_along_axis(meets[rows], first, -1)[..., None]
        u_k = np.where(keep, np.take_along_axis(u[rows], first[..., None], 1), np.nan)
        v_k = np.take_along_axis(v[rows], first[..., None], 1)  # only the footprints that meet the mirror
        area[rows] = _covered(u_k, v_k, half_w, half_l)
        start += chunk
    fraction = [area]
    return np.concatenate(fraction).reshape(lead) / (mirror_width * mirror_length) if fraction else np.zeros(lead)


def _covered(u, v, half_w: float, half_l: float) -> np.ndarray:
    """Area [m^2] of (-half_w, half_w) x (-half_l, half_l) covered by footprints (P, K, C): :func:`covered_fraction`."""
    nu, nv = np.roll(u, -1, axis=-1), np.roll(v, -1, axis=-1)
    with np.errstate(invalid="ignore", divide="ignore"):
        at_ends = [u + (side - v) / (nv - v) * (nu - u) for side in (-half_l, half_l)]  # edges meet v = -+l/2
    at_ends = [np.where((x - np.minimum(u, nu)) * (np.maximum(u, nu) - x) >= 0, x, np.nan) for x in at_ends]
    corners_and_cuts = np.concatenate([u, *at_ends], axis=-1)
    edges = np.concatenate(
        [
            np.clip(corners_and_cuts, -half_w, half_w).reshape(u.shape[0], -1),
            np.tile([-half_w, half_w], (u.shape[0], 1)),
        ],
        -1,
    )
    edges = np.sort(np.where(np.isfinite(edges), edges, half_w), axis=-1)
    # corners off the mirror clip to its sides: drop the repeated edges (zero-width slabs), the distinct first
    distinct = np.concatenate([np.ones((len(edges), 1), bool), np.diff(edges, axis=-1) > 0], -1)
    order = np.argsort(~distinct, axis=-1, kind="stable")[:, : max(int(distinct.sum(-1).max()), 2)]
    edges = np.where(
        np.take_along_axis(distinct, order, -1), np.take_along_axis(edges, order, -1), half_w
    )  # sorted, then half_w: the padding's slabs have zero width
    steps = np.arange(SUB_SLABS) / SUB_SLABS  # each slab cut in SUB_SLABS: the midpoint rule where edges cross
    edges = np.concatenate(
        [(edges[:, :-1, None] + np.diff(edges)[:, :, None] * steps).reshape(len(edges), -1), edges[:, -1:]], -1
    )
    middle, slab = (edges[..., 1:] + edges[..., :-1]) / 2, np.diff(edges, axis=-1)  # (P, S)
    x = middle[..., :, None, None]
    ua, va = u[..., None, :, :], v[..., None, :, :]
    ub, vb = np.roll(ua, -1, axis=-1), np.roll(va, -1, axis=-1)  # each edge: corner to the next
    with np.errstate(invalid="ignore", divide="ignore"):
        t = (x - ua) / (ub - ua)
        cross = va + t * (vb - va)
    cut = (t >= 0) & (t <= 1) & np.isfinite(cross)
    low = np.clip(np.min(np.where(cut, cross, np.inf), axis=-1), -half_l, half_l)  # (P, S, K)
    high = np.clip(np.max(np.where(cut, cross, -np.inf), axis=-1), -half_l, half_l)
    covered = interval_union_length(np.where(high > low, low, 0.0), np.where(high > low, high, 0.0))
    return np.sum(slab * covered, axis=-1)


def row_losses(
    sun,
    normals,
    mirror_distances,
    mirror_width,
    mirror_length=None,
    pitch=None,
    only_lost: bool = False,
    receiver: tuple[float, float] | None = None,
) -> dict:
    """Shading, blocking and the light lost to both, for every mirror of a row of mirrors at each instant.

    Parameters
    ----------
    sun : array-like, shape (T, 3)  [-]
        Unit vector toward the sun, plant frame.
    normals : array-like, shape (T, N, 3)  [-]
        The N rows' unit normals (flat mirrors).
    mirror_distances : array-like, shape (N,)  [m]
    mirror_width : float  [m]
    mirror_length, pitch : float, optional  [m]
        Length l and pitch p along the row (default p = l: contiguous) of two-axis mirrors in a section;
        without, long continuous rows (single-axis: the exact 2-D transverse geometry).
    only_lost : bool, default False
        Compute ``lost`` only (two-axis: a third of the cost).
    receiver : (float, float), optional  [m]
        The receiver's height above the pivots and width across: its own shadow
        (:mod:`heliostep.solar.receiver_shadow`) joins the neighbours' (their union); None: none.

    Returns
    -------
    dict of numpy.ndarray, shape (T, N)  [-]
        ``shading``, ``blocking`` and ``lost`` (their union), fractions of the mirror's area; with
        ``receiver``, ``receiver_shadow`` too. The collected beam is DNI (S . n) (1 - lost) w l.
    """
    sun = as_float_array(sun)
    normal = as_float_array(normals)
    reflected = reflected_direction(sun[:, None, :], normal)
    width = check_positive(mirror_width, "mirror_width", "m")
    sun_rows = np.broadcast_to(sun[:, None, :], normal.shape)
    band = None if receiver is None else _receiver_band(sun_rows, normal, mirror_distances, receiver)
    if mirror_length is None:
        return _single_axis_losses(sun_rows, reflected, normal, mirror_distances, width, band)
    length = check_positive(mirror_length, "mirror_length", "m")
    pitch = length if pitch is None else pitch
    shade_u, shade_v = footprints(sun_rows, normal, mirror_distances, width, length, pitch)
    block_u, block_v = footprints(reflected, normal, mirror_distances, width, length, pitch)
    out = {}
    if band is not None:
        own_u, own_v = _band_footprint(band, width + length)
        shade_u, shade_v = np.concatenate([shade_u, own_u], axis=-2), np.concatenate([shade_v, own_v], axis=-2)
        if not only_lost:
            out["receiver_shadow"] = covered_fraction(own_u, own_v, width, length)
    both_u, both_v = np.concatenate([shade_u, block_u], axis=-2), np.concatenate([shade_v, block_v], axis=-2)
    out["lost"] = covered_fraction(both_u, both_v, width, length)
    if not only_lost:
        out["shading"] = covered_fraction(shade_u, shade_v, width, length)
        out["blocking"] = covered_fraction(block_u, block_v, width, length)
    return out


def _receiver_band(sun_rows, normal, mirror_distances, receiver: tuple[float, float]) -> tuple:
    """(g0, a, b, ahead, half): the receiver's shadow band on each mirror and its half-width [m]."""
    distances = np.atleast_1d(as_float_array(mirror_distances)).ravel()
    half = check_positive(receiver[1], "receiver width", "m") / 2.0
    return (*receiver_shadow_band(sun_rows, normal, distances, receiver[0]), half)


def _single_axis_losses(sun_rows, reflected, normal, mirror_distances, width: float, band) -> dict:
    """:func:`row_losses` of long single-axis rows: the union of intervals across each mirror's width."""
    spans = [_across_intervals(direction, normal, mirror_distances, width) for direction in (sun_rows, reflected)]
    (shade_low, shade_high), (block_low, block_high) = spans
    out = {}
    if band is not None:
        own_low, own_high = _band_interval(band, width)
        out["receiver_shadow"] = interval_union_length(own_low, own_high) / width
        shade_low, shade_high = np.concatenate([shade_low, own_low], -1), np.concatenate([shade_high, own_high], -1)
    both = interval_union_length(
        np.concatenate([shade_low, block_low], -1), np.concatenate([shade_high, block_high], -1)
    )
    out["shading"] = interval_union_length(shade_low, shade_high) / width
    out["blocking"] = interval_union_length(block_low, block_high) / width
    out["lost"] = both / width
    return out


def _band_interval(band, width: float) -> tuple[np.ndarray, np.ndarray]:
    """The receiver's shadow band |g0 + a s| <= half on single-axis rows (b = 0: e_v is y) as an interval
    of s [m], (T, N, 1), clipped to the width; empty (0, 0) where it casts none. ``band``: (g0, a, b,
    ahead, half), :func:`heliostep.solar.receiver_shadow.receiver_shadow_band` and the half-width [m]."""
    g0, a, _, ahead, half = band
    with np.errstate(invalid="ignore", divide="ignore"):
        ends = [(side - g0) / a for side in (-half, half)]
    flat = np.abs(a) < 1e-12  # the sun's ray along the mirror's width: all of it or none
    low = np.where(flat, np.where(np.abs(g0) <= half, -width / 2, 0.0), np.minimum(*ends))
    high = np.where(flat, np.where(np.abs(g0) <= half, width / 2, 0.0), np.maximum(*ends))
    low, high = (np.where(ahead, np.clip(x, -width / 2, width / 2), 0.0)[..., None] for x in (low, high))
    return low, high


def _band_footprint(band, reach: float) -> tuple[np.ndarray, np.ndarray]:
    """The receiver's shadow band |g0 + a s + b t| <= half as a footprint (T, N, 1, 8) in the mirror's
    (e_u, e_v) frame: the parallelogram between its two edges, ``reach`` [m] both ways along them (past
    the mirror: :func:`covered_fraction` clips it), corners in order, the last repeated; NaN where none.
    ``band``: as :func:`_band_interval`'s."""
    g0, a, b, ahead, half = band
    norm2 = a**2 + b**2
    ok = ahead & (norm2 > 1e-24)
    with np.errstate(invalid="ignore", divide="ignore"):
        edge = [((side - g0) / norm2)[..., None] * np.stack([a, b], -1) for side in (-half, half)]  # on each edge
        along = np.stack([b, -a], -1) / np.sqrt(norm2)[..., None]  # the band's direction in (s, t)
    corners = [edge[0] - reach * along, edge[1] - reach * along, edge[1] + reach * along, edge[0] + reach * along]
    corners += [corners[-1]] * 4  # the format of footprints(): 8 slots, repeated corners are zero-length edges
    uv = np.stack(corners, axis=-2)  # (T, N, 8, 2)
    uv = np.where(ok[..., None, None], uv, np.nan)
    return uv[..., None, :, 0], uv[..., None, :, 1]


def coarse_instants(up, every: int, labels=None) -> np.ndarray:
    """The instants :func:`interpolated_at_coarse_instants` computes: every ``every``-th of ``up`` (indices,
    increasing: those with the sun up) and the first and last of each day (``labels``: a day label per
    instant; one day without), sorted."""
    up = np.asarray(up)
    if labels is None:
        return np.unique(np.concatenate([up[::every], up[-1:]]))
    day = np.asarray(labels)[up]
    turns = np.r_[True, day[1:] != day[:-1]]
    return np.unique(np.concatenate([up[::every], up[turns], up[np.r_[turns[1:], True]]]))


def interpolated_at_coarse_instants(up, every: int, sample, labels=None) -> np.ndarray:
    """Losses computed at coarse instants only and interpolated between: ``sample(coarse)`` (the
    values, (K, N), at the instants of index ``coarse``: :func:`coarse_instants`), linear in the
    instants' index to each of ``up``. Returns (len(up), N)."""
    coarse = coarse_instants(up, every, labels)
    return interpolated(up, coarse, sample(coarse))


def interpolated(up, coarse, sampled) -> np.ndarray:
    """``sampled`` (K, N) at the instants ``coarse`` interpolated linearly in the instants' index to each of
    ``up``, (len(up), N)."""
    sampled = np.asarray(sampled)
    return np.stack([np.interp(up, coarse, sampled[:, column]) for column in range(sampled.shape[1])], axis=-1)
