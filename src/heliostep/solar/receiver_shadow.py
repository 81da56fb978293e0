"""The receiver's own shadow on the mirrors below it.

The receiver (the absorber tube, or the secondary concentrator around it) runs along y at x = 0,
z = h, above the mirrors' pivots (frames as in :mod:`heliostep.solar`). Infinite along y, it hides
a mirror's point F from the sun when F's sun ray passes its axis, in the cross-section, within half
the receiver's width across, toward the sun ([shading]: the receiver's shadow is the third
geometric loss of a linear Fresnel field's mirrors, e.g. Sharma et al., Solar Energy 2015, with the
neighbours' shading and blocking, :mod:`heliostep.solar.shading`).

With sigma = (S_x, S_z) / |(S_x, S_z)| the sun's direction in the cross-section and
e = (-sigma_z, sigma_x) across it, the ray through F = C + s e_u + t e_v (the mirror's width and
length axes, :func:`heliostep.solar.optics.mirror_axes`; C = (d, 0, 0)) passes the axis A = (0, h)
at the signed distance (exact: a straight line and an infinite cylinder)::

    g(s, t) = (F - A)_xz . e = g0 + a s + b t,   g0 = -d sigma_z - h sigma_x,
    a = e_u,xz . e,   b = e_v,xz . e,

and the receiver is toward the sun when (A - C)_xz . sigma > 0. The shadow is the band |g| <= r on
the mirror, r half the receiver's width: over the mirror's uniform (s, t), g - g0 is a box of
half-width |a| w / 2 convolved with a box of half-width |b| l / 2, a trapezoid, and the share is its
CDF's difference over the window g0 +- r (:func:`trapezoid_cdf`, piecewise quadratic): **exact** for a
flat mirror (the band's edges are straight lines on it). A two-axis mirror's tilted long axis (b != 0) shears the
band across the mirror. The sun's disc blurs the band's edges by lambda x 4.65 mrad (about 14 mm at
3 m): neglected, as for the neighbours' shadows.

The receiver's width across, the shadow's 2 r: the absorber's diameter for a bare tube (its glass
envelope transmits tau of the light, which is already in the optical chain) or the secondary's
aperture width (its casing is at least as wide: a lower bound).
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
