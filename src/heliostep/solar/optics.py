"""Optics of one mirror: reflected ray, where it meets the tube, cosine factor and end effect.

Conventions: see :mod:`heliostep.solar` (plant frame x across, y along the tube, z up; tube
axis at x = 0, z = ``tube_height``; a mirror at x = ``mirror_distance``, y = 0, z = 0;
n = R_y(primary) R_x(secondary) z_hat).

"""

from __future__ import annotations

import numpy as np

from heliostep.solar.checks import as_float_array, check_positive, check_range

#: Half-angle of the sun's disc [rad] (Rabl 1985; seed 002 quotes +-4.6 mrad).
SUN_HALF_ANGLE = 4.65e-3
#: Standard deviation of the pillbox sun's 1-D projection, SUN_HALF_ANGLE / 2 [rad].
SUN_SIGMA = SUN_HALF_ANGLE / 2.0


def mirror_normal(primary, secondary):
    """Unit normal of a two-axis mirror from its two rotation angles.

    Parameters
    ----------
    primary, secondary : array-like  [rad]
        Rotations as in :func:`heliostep.solar.tracking.two_axis_angles_from_normal`.

    Returns
    -------
    normal_x, normal_y, normal_z : arrays  [-]
        n = (cos q sin p, -sin q, cos q cos p).
    """
    p, q = as_float_array(primary), as_float_array(secondary)
    return np.cos(q) * np.sin(p), -np.sin(q) * np.ones_like(p), np.cos(q) * np.cos(p)  # [paper], eqs. 3-4


def mirror_axes(normal_x, normal_y, normal_z):
    """Width and length axes of flat mirrors from their unit normals.

    Parameters
    ----------
    normal_x, normal_y, normal_z : array-like  [-]
        Unit normal, n = R_y(p) R_x(q) z_hat = (cos q sin p, -sin q, cos q cos p).

    Returns
    -------
    n, e_u, e_v : numpy.ndarray, shape (..., 3)  [-]
        e_u = R_y(p) x_hat = (cos p, 0, -sin p) (across the tube), e_v = n x e_u = R_y(p) R_x(q) y_hat.
    """
    n = np.stack(np.broadcast_arrays(*(as_float_array(c) for c in (normal_x, normal_y, normal_z))), axis=-1)
    horizontal = np.hypot(n[..., 0], n[..., 2])
    with np.errstate(invalid="ignore", divide="ignore"):
        e_u = np.stack([n[..., 2], np.zeros_like(horizontal), -n[..., 0]], axis=-1) / horizontal[..., None]
    e_v = np.cross(n, e_u)  # [paper], eqs. 3-6: R_y(p) R_x(q) y_hat
    return n, e_u, e_v


def reflect(sun_x, sun_y, sun_z, normal_x, normal_y, normal_z):
    """Direction of the reflected central ray.

    Parameters
    ----------
    sun_x, sun_y, sun_z : array-like  [-]
        Unit vector toward the sun.
    normal_x, normal_y, normal_z : array-like  [-]
        Unit mirror normal.

    Returns
    -------
    ray_x, ray_y, ray_z : arrays  [-]
        r = 2 (S . n) n - S (law of reflection), a unit vector.
    """
    s = [as_float_array(c) for c in (sun_x, sun_y, sun_z)]
    n = [as_float_array(c) for c in (normal_x, normal_y, normal_z)]
    dot = s[0] * n[0] + s[1] * n[1] + s[2] * n[2]
    return tuple(2.0 * dot * nc - sc for sc, nc in zip(s, n))  # law of reflection, r = 2(S.n)n - S


def cosine_factor(sun_x, sun_y, sun_z, normal_x, normal_y, normal_z):
    """Cosine of the incidence angle on the mirror, clipped at 0 (sun behind the mirror).

    Returns
    -------
    array  [-]
        max(S . n, 0): the fraction of the DNI falling on a unit of mirror area.
    """
    dot = sum(
        as_float_array(a) * as_float_array(b) for a, b in zip((sun_x, sun_y, sun_z), (normal_x, normal_y, normal_z))
    )
    return np.clip(dot, 0.0, None)  # Lambert's cosine law


def receiver_miss(ray_x, ray_y, ray_z, mirror_distance, tube_height):
    """Where the central ray passes the tube axis (x = 0, z = h, parallel to y).

    The point of the ray closest to the axis in the cross-section (the x-z projection) is
    where it crosses the tube's cross-section plane through the axis.

    Parameters
    ----------
    ray_x, ray_y, ray_z : array-like  [-]
        Unit reflected ray from the mirror at (d, 0, 0).
    mirror_distance : float or array-like  [m]
    tube_height : float  [m]

    Returns
    -------
    transverse : array  [m]
        Signed perpendicular distance of the ray's cross-section projection from the tube
        axis; positive when a rising ray passes on the +x side of the axis.
    longitudinal : array  [m]
        y of the ray at that point: how far along the tube the light lands from the
        mirror's own cross-section.
    slant : array  [m]
        Path length from the mirror to that point (NaN if the ray goes down or away).
    """
    tube_height = check_positive(tube_height, "tube_height", "m")
    d = as_float_array(mirror_distance)
    rx, ry, rz = (as_float_array(c) for c in (ray_x, ray_y, ray_z))
    across = np.hypot(rx, rz)  # length of the ray's cross-section projection
    with np.errstate(invalid="ignore", divide="ignore"):
        t = (-d * rx + tube_height * rz) / across**2  # parameter of closest approach in x-z
        transverse = (rx * tube_height + rz * d) / across  # 2-D cross product (T - M) x r / |r_xz|
        t = np.where(t > 0, t, np.nan)
    return transverse, t * ry, t * np.sqrt(rx**2 + ry**2 + rz**2)


def end_fraction(longitudinal, mirror_length, mirror_y, tube_start, tube_end):
    """Fraction of a mirror's light that lands on the tube's length (the end effect).

    The mirror (length l along y, centred at y_m) lights [y_m + k - l/2, y_m + k + l/2] of
    the tube's axis, k being the longitudinal shift of its light.

    Parameters
    ----------
    longitudinal : array-like  [m]
        Shift k (:func:`receiver_miss` or :func:`heliostep.solar.tracking.end_loss_length`).
    mirror_length : float  [m]
        Length l of the mirror along the tube, > 0.
    mirror_y : float  [m]
        y of the mirror's centre.
    tube_start, tube_end : float  [m]
        y of the tube's two ends.

    Returns
    -------
    array  [-]
        Overlap length / l within [0, 1]; 0 where k is NaN.
    """
    length = check_positive(mirror_length, "mirror_length", "m")
    k = as_float_array(longitudinal)
    low, high = min(tube_start, tube_end), max(tube_start, tube_end)
    centre = mirror_y + k
    with np.errstate(invalid="ignore"):
        overlap = np.clip(np.minimum(centre + length / 2, high) - np.maximum(centre - length / 2, low), 0.0, length)
    return np.nan_to_num(overlap / length, nan=0.0)


def optical_chain(reflectivity, transmittance, absorptance):
    """Product rho tau alpha of mirror reflectivity, glass transmittance and tube absorptance.

    Returns
    -------
    float  [-]
        rho * tau * alpha (seed 004, Section 3: 0.80 * 0.85 * 0.95).
    """
    values = [
        check_range(v, n, 0.0, 1.0, "-")
        for v, n in ((reflectivity, "reflectivity"), (transmittance, "transmittance"), (absorptance, "absorptance"))
    ]
    return values[0] * values[1] * values[2]  # seed 004, energy chain
