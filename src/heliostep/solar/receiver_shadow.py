"""The receiver's own shadow on the mirrors below it.

The shadow is a band on the mirror, a trapezoid's CDF over its uniform width and length: exact for
a flat mirror.

Details: docs/light.md, ``heliostep.solar.receiver_shadow``.
"""

from __future__ import annotations

import numpy as np

from heliostep.solar.checks import as_float_array, check_positive
from heliostep.solar.optics import mirror_axes

__all__ = ["receiver_shadow_band", "receiver_shadow_fraction", "receiver_width", "trapezoid_cdf"]


def receiver_width(tube_diameter: float, secondary: dict | None = None) -> float:
    """The receiver's width across [m] that casts the shadow: the secondary's aperture, else the absorber."""
    return float(secondary["aperture_width"]) if secondary else float(tube_diameter)


def receiver_shadow_band(sun, normals, mirror_distances, tube_height):
    """The receiver's shadow band on each mirror, g(s, t) = g0 + a s + b t (the module's docstring).

    Parameters
    ----------
    sun : array-like, shape (..., 3)  [-]
        Unit vector toward the sun, plant frame; broadcast against ``normals``.
    normals : array-like, shape (..., 3)  [-]
        The mirrors' unit normals (flat mirrors).
    mirror_distances : array-like  [m]
        Their pivots' x, broadcast against ``normals[..., 0]``.
    tube_height : float  [m]
        Of the receiver's axis above the pivots.

    Returns
    -------
    g0, a, b : numpy.ndarray  [m], [-], [-]
        The band's offset at the mirror's centre and its slopes along e_u and e_v.
    ahead : numpy.ndarray of bool
        The receiver is toward the sun from the mirror (else it casts no shadow on it).
    """
    sun, normal = as_float_array(sun), as_float_array(normals)
    h = check_positive(tube_height, "tube_height", "m")
    d = as_float_array(mirror_distances)
    across = np.hypot(sun[..., 0], sun[..., 2])
    with np.errstate(invalid="ignore", divide="ignore"):
        sig_x, sig_z = sun[..., 0] / across, sun[..., 2] / across
    _, e_u, e_v = mirror_axes(normal[..., 0], normal[..., 1], normal[..., 2])
    e_x, e_z = -sig_z, sig_x
    g0 = -d * sig_z - h * sig_x  # (C - A)_xz . e
    a = e_u[..., 0] * e_x + e_u[..., 2] * e_z
    b = e_v[..., 0] * e_x + e_v[..., 2] * e_z
    ahead = (-d * sig_x + h * sig_z > 0.0) & np.isfinite(g0)  # (A - C)_xz . sigma > 0
    return g0, a, b, ahead


def receiver_shadow_fraction(sun, normals, mirror_distances, tube_height, width, mirror_width, mirror_length):
    """Share of each mirror in the receiver's shadow [-] (exact for flat mirrors: the module's docstring).

    Parameters
    ----------
    sun, normals, mirror_distances, tube_height
        As :func:`receiver_shadow_band`.
    width : float  [m]
        The receiver's width across (:func:`receiver_width`).
    mirror_width, mirror_length : float  [m]
    """
    r = check_positive(width, "receiver width", "m") / 2.0
    w, length = check_positive(mirror_width, "mirror_width", "m"), check_positive(mirror_length, "mirror_length", "m")
    g0, a, b, ahead = receiver_shadow_band(sun, normals, mirror_distances, tube_height)
    half_a, half_b = np.abs(a) * w / 2.0, np.abs(b) * length / 2.0
    big, small = np.maximum(half_a, half_b), np.minimum(half_a, half_b)
    fraction = trapezoid_cdf(r - g0, big, small) - trapezoid_cdf(-r - g0, big, small)
    return np.where(ahead, np.clip(np.nan_to_num(fraction), 0.0, 1.0), 0.0)


def trapezoid_cdf(z, half_a, half_b):
    """P(U(-A, A) + U(-B, B) <= z), A >= B >= 0: the CDF of a trapezoid (of a box when B = 0, a step at 0
    when A = 0), in the closed form that needs no differences of large numbers.

    Parameters
    ----------
    z, half_a, half_b : array-like  [m]

    Returns
    -------
    numpy.ndarray  [-]
        0 below -A-B; (z + A + B)^2 / (8 A B) to -A+B; (z + A) / (2 A) to A-B; 1 - (A + B - z)^2 / (8 A B)
        to A+B; 1 above.
    """
    z, a, b = np.broadcast_arrays(*(as_float_array(x) for x in (z, half_a, half_b)))
    with np.errstate(invalid="ignore", divide="ignore"):
        ramp = np.clip((z + a) / (2.0 * a), 0.0, 1.0)  # the box's CDF
        low = (z + a + b) ** 2 / (8.0 * a * b)
        high = 1.0 - (a + b - z) ** 2 / (8.0 * a * b)
    cdf = np.where(z <= -a + b, low, np.where(z >= a - b, high, ramp))
    cdf = np.where(b > 0.0, cdf, ramp)  # one box: no quadratic ends
    cdf = np.where(z <= -a - b, 0.0, np.where(z >= a + b, 1.0, cdf))
    return np.where(a > 0.0, cdf, (z >= 0.0) * 1.0)
