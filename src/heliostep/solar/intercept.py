"""Intercept of a finite mirror's light by the receiver: a bare absorber tube or a secondary concentrator.

The mirror's image at the receiver is a box (its width), a box (a two-axis mirror's shear) and a
Gaussian (sun, slope and specularity errors) convolved, integrated over the receiver in closed form;
a secondary concentrator adds what it accepts within its half-angle.

Details: docs/light.md, ``heliostep.solar.intercept``.
"""

from __future__ import annotations

import numpy as np
from scipy.special import ndtr

from heliostep.solar.checks import as_float_array, check_positive, check_range
from heliostep.solar.optics import SUN_SIGMA, receiver_miss

#: RMS surface slope error per axis of a silvered-glass reflector [rad]: SolarPILOT's default
#: heliostat surface slope error (NREL SolarPILOT / HALOS, ``err_surface_x`` = ``err_surface_y``
#: = 1.53 mrad). No seed gives one for this mirror: seed 002's b / (8 f) = 2.22 mrad is the shape
#: error of its flat 0.533 m stripes on a 30 m heliostat, not a surface error.
SURFACE_SLOPE_ERROR = 1.53e-3

_INV_SQRT_2PI = 1.0 / np.sqrt(2.0 * np.pi)


def shape_slope_error(mirror_width, focal_length, slant):
    """Mean slope deviation of a mirror from the cylinder that would focus at its slant distance.

    Seed 002's b / (8 f) (its eq. 13: a flat stripe of width b standing in for a parabola of focal
    length f) with this mirror's width and, for a curved mirror of focal length f at slant L, the
    parabola of curvature 1/f - 1/L missing: (b / 8) |1/f - 1/L|; flat (f = None): b / (8 L).
    It is not added to the random slope error: the image's width term carries it exactly
    (the box of :func:`mirror_image` is 8 L times it, before projection).

    Parameters
    ----------
    mirror_width : float  [m]
    focal_length : float or None  [m]
        None: a flat mirror.
    slant : array-like  [m]

    Returns
    -------
    array  [rad]
    """
    width = check_positive(mirror_width, "mirror_width", "m")
    curvature = 0.0 if focal_length is None else 1.0 / check_positive(focal_length, "focal_length", "m")
    return width / 8.0 * np.abs(curvature - 1.0 / as_float_array(slant))  # seed 002, eq. 13 (b / 8f)


def _dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def mirror_image(sun, primary, secondary, ray, slant, width, length, focal_length=None):
    """Half-widths of a finite mirror's image across the tube and the slope error's gain.

    Parameters
    ----------
    sun : sequence of 3 arrays  [-]
        Unit vector toward the sun.
    primary, secondary : array-like  [rad]
        The mirror's angles (:func:`heliostep.solar.optics.mirror_normal`).
    ray : sequence of 3 arrays  [-]
        The central reflected ray.
    slant : array-like  [m]
        Central ray's path to the receiver.
    width, length : float  [m]
        The mirror's width (across its secondary axis) and length (its long axis).
    focal_length : float or None  [m]
        Curvature about the long axis; None: flat.

    Returns
    -------
    dict of arrays
        ``across`` A [m] (the width's half image), ``shear`` B [m] (the length's, two-axis),
        their signed values ``across_signed``, ``shear_signed``; ``nearer`` [m], how much nearer
        the receiver the length's end t = l/2 is (a tilted long axis); ``across_rate`` [m], the
        change of the signed A there (a curved mirror's focus moves with the distance);
        ``slope_gain`` |g| [-], ``fan`` the curved mirror's angle spread per metre of width in
        the cross-section [rad/m], ``rho`` |r_xz| [-].
    """
    p, q = as_float_array(primary), as_float_array(secondary)
    u = (np.cos(p), np.zeros_like(p), -np.sin(p))
    v = (np.sin(q) * np.sin(p), np.cos(q) * np.ones_like(p), np.sin(q) * np.cos(p))
    n = (np.cos(q) * np.sin(p), -np.sin(q) * np.ones_like(p), np.cos(q) * np.cos(p))  # [paper], eqs. 3-4
    s = [as_float_array(c) for c in sun]
    r = [as_float_array(c) for c in ray]
    rho = np.hypot(r[0], r[2])
    with np.errstate(invalid="ignore", divide="ignore"):
        e = (-r[2] / rho, np.zeros_like(rho), r[0] / rho)
    sn, ne, ue = _dot(s, n), _dot(n, e), _dot(u, e)
    k = _dot(s, u) * ne + sn * ue  # the curved mirror's focusing, first order in s / f
    curvature = 0.0 if focal_length is None else 1.0 / focal_length
    across = (ue - as_float_array(slant) * curvature * k) * width / 2.0
    shear = _dot(v, e) * length / 2.0
    with np.errstate(invalid="ignore", divide="ignore"):
        nearer = (v[0] * r[0] + v[2] * r[2]) / rho**2 * length / 2.0  # the slant's change at the length's end
    g = [ne * (sc - _dot(s, n) * nc) + sn * (ec - ne * nc) for sc, ec, nc in zip(s, e, n)]
    with np.errstate(invalid="ignore", divide="ignore"):
        fan = np.abs(k) * curvature / rho
    return {
        "across": np.abs(across),
        "shear": np.abs(shear),
        "across_signed": across,
        "shear_signed": shear,
        "across_rate": nearer * curvature * k * width / 2.0,
        "nearer": nearer,
        "slope_gain": np.sqrt(_dot(g, g)),
        "fan": fan,
        "rho": rho,
    }


def _g1(x, sigma):
    """Antiderivative of Phi(x / sigma) in x [m]."""
    z = x / sigma
    return x * ndtr(z) + sigma * _INV_SQRT_2PI * np.exp(-0.5 * z**2)


def _g2(x, sigma, sigma_squared):
    """Antiderivative of :func:`_g1` in x [m^2] (``sigma_squared`` = sigma**2, computed once by the caller)."""
    z = x / sigma
    return 0.5 * (x**2 + sigma_squared) * ndtr(z) + 0.5 * x * sigma * _INV_SQRT_2PI * np.exp(-0.5 * z**2)


def _image_kinds(a, b, sigma):
    """Which closed form each row's image takes in :func:`_below`: ``point`` (a, b negligible
    against sigma: the Gaussian alone) and ``single`` (b negligible: one box and the Gaussian);
    the rest take both boxes."""
    point = a <= 1e-4 * sigma
    return point, ~point & (b <= 1e-4 * np.maximum(a, sigma))


def _below(z, a, b, sigma, kinds):
    """P(U(-a, a) + U(-b, b) + N(0, sigma^2) <= z), a >= b >= 0, sigma > 0.

    Each row takes one closed form (``kinds``: :func:`_image_kinds` of a, b, sigma, computed once
    for the z's of one image) and only that one is evaluated: the rows of a kind are computed by
    the same operations on the same values as over the whole array, so the result is the same bit
    for bit as evaluating every form and choosing."""
    point, single = kinds
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        if not (point.any() or single.any()):  # the usual case: every row a double box
            return _double_box(z, a, b, sigma)
        z, a, b, sigma, point, single = np.broadcast_arrays(z, a, b, sigma, point, single)
        out = np.empty(z.shape)
        double = ~(point | single)
        out[double] = _double_box(z[double], a[double], b[double], sigma[double])
        za, aa, sa = z[single], a[single], sigma[single]
        out[single] = (_g1(za + aa, sa) - _g1(za - aa, sa)) / (2.0 * aa)  # erf's of the box
        out[point] = ndtr(z[point] / sigma[point])
    return out


def _double_box(z, a, b, sigma):
    """:func:`_below` where both boxes count: the trapezoid's CDF convolved with the Gaussian."""
    s2 = sigma**2
    return (
        _g2(z + a + b, sigma, s2) - _g2(z + a - b, sigma, s2) - _g2(z - a + b, sigma, s2) + _g2(z - a - b, sigma, s2)
    ) / (4.0 * a * b)


def box_gauss_fraction(centre, half_a, half_b, sigma, half_window):
    """Share of a box * box * Gaussian image within a window: P(|c + U_a + U_b + N| <= W).

    Parameters
    ----------
    centre : array-like  [m]
        Offset c of the image's centre from the window's.
    half_a, half_b : array-like  [m]
        Half-widths of the two uniform parts, >= 0.
    sigma : array-like  [m]
        Standard deviation of the Gaussian part, >= 0 (floored at 1e-12 m).
    half_window : array-like  [m]
        Half-width W of the window.

    Returns
    -------
    array  [-]
        F(W - c) - F(-W - c) with F the image's CDF: with G1, G2 the first and second
        antiderivatives of the normal CDF, F = [G2(z+a+b) - G2(z+a-b) - G2(z-a+b) + G2(z-a-b)] / (4ab)
        (one box: [G1(z+a) - G1(z-a)] / 2a; no box: Phi(z / sigma)); 0 where c is NaN.
    """
    c = as_float_array(centre)
    a, b = np.abs(as_float_array(half_a)), np.abs(as_float_array(half_b))
    big, small = np.maximum(a, b), np.minimum(a, b)
    sigma = np.maximum(as_float_array(sigma), 1e-12)
    w = as_float_array(half_window)
    kinds = _image_kinds(big, small, sigma)
    fraction = _below(w - c, big, small, sigma, kinds) - _below(-w - c, big, small, sigma, kinds)
    return np.clip(np.nan_to_num(fraction, nan=0.0), 0.0, 1.0)


def angular_sigma(slope_gain, slope_error, specularity, sun_sigma: float = SUN_SIGMA):
    """Standard deviation of the reflected rays' angle across the tube [rad]:
    sqrt(sigma_sun^2 + 4 sigma_s^2 |g|^2 + sigma_spec^2) (see the module's docstring)."""
    return np.sqrt(sun_sigma**2 + (2.0 * slope_error * slope_gain) ** 2 + specularity**2)  # law of reflection


def intercept(sun, primary, secondary, ray, distance, tube_height, receiver, mirror):
    """Intercept of a finite mirror's reflected light by the receiver, at each instant.

    Parameters
    ----------
    sun, ray : sequences of 3 arrays  [-]
        Unit vectors toward the sun and of the central reflected ray.
    primary, secondary : array-like  [rad]
        The mirror's angles.
    distance, tube_height : float  [m]
        The mirror's d and the tube's axis height h.
    receiver : Mapping
        ``tube_diameter`` D [m] and ``secondary``: None (a bare tube) or a mapping with
        ``aperture_width`` [m], ``acceptance_half_angle`` [rad] and ``reflectivity`` [-].
    mirror : Mapping
        ``width``, ``length`` [m], ``focal_length`` [m] or None (flat), ``slope_error`` and
        ``specularity`` [rad].

    Returns
    -------
    dict of arrays
        ``intercept`` gamma [-], ``transverse_miss_m``, ``longitudinal_miss_m``, ``slant_m`` [m]
        (the central ray at the tube's axis, :func:`heliostep.solar.optics.receiver_miss`),
        ``image_half_width_m`` (A + B) [m].
    """
    diameter = check_positive(receiver["tube_diameter"], "tube_diameter", "m")
    width = check_positive(mirror["width"], "mirror_width", "m")
    length = check_positive(mirror["length"], "mirror_length", "m")
    focal = mirror.get("focal_length")
    focal = None if focal is None else check_positive(focal, "focal_length", "m")
    transverse, longitudinal, slant = receiver_miss(ray[0], ray[1], ray[2], distance, tube_height)
    image = mirror_image(sun, primary, secondary, ray, slant, width, length, focal)
    sigma = angular_sigma(image["slope_gain"], mirror.get("slope_error", 0.0), mirror.get("specularity", 0.0))
    gamma = _slab_fraction(transverse, image, sigma, slant, diameter / 2.0)
    second = receiver.get("secondary")
    if second is not None:
        gamma = _secondary(gamma, ray, distance, tube_height - diameter / 2.0, image, sigma, second, width, focal)
    return {
        "intercept": gamma,
        "transverse_miss_m": transverse,
        "longitudinal_miss_m": longitudinal,
        "slant_m": slant,
        "image_half_width_m": image["across"] + image["shear"],
    }


#: Slabs across the mirror's length in :func:`_slab_fraction`.
LENGTH_SLABS = 8


def _slab_fraction(miss, image, sigma, slant, half_window):
    """The image's share within the window, the length cut into :data:`LENGTH_SLABS` slabs: each a
    box (its width's A at the slab's distance to the receiver) * box (the slab's shear) * Gaussian
    (the angular spread over the slab's slant), exact but for A's change within a slab (1/8 of the
    curved, tilted mirror's change of focus along its length)."""
    total = 0.0
    for j in range(LENGTH_SLABS):
        tau = -1.0 + (2.0 * j + 1.0) / LENGTH_SLABS  # the slab's centre in half-lengths
        distance = slant - tau * image["nearer"]
        total = total + box_gauss_fraction(
            miss - tau * image["shear_signed"],
            image["across_signed"] + tau * image["across_rate"],
            image["shear"] / LENGTH_SLABS,
            distance * sigma,
            half_window,
        )
    return total / LENGTH_SLABS


def _secondary(direct, ray, distance, aperture_height, image, sigma, second, width, focal):
    """A secondary concentrator's intercept from the bare tube's (see the module's docstring)."""
    aperture = check_positive(second["aperture_width"], "secondary.aperture_width", "m")
    theta = check_range(second["acceptance_half_angle"], "secondary.acceptance_half_angle", 0.0, np.pi / 2, "rad")
    reflectivity = check_range(second["reflectivity"], "secondary.reflectivity", 0.0, 1.0, "-")
    miss, _, slant = receiver_miss(ray[0], ray[1], ray[2], distance, aperture_height)
    psi = np.arctan2(as_float_array(ray[0]), as_float_array(ray[2]))  # the central ray from the vertical
    through = _slab_fraction(miss, image, sigma, slant, aperture / 2.0 * np.cos(psi))
    fan = 0.0 if focal is None else image["fan"] * width / 2.0
    with np.errstate(invalid="ignore", divide="ignore"):
        accept = box_gauss_fraction(psi, fan, 0.0, sigma / image["rho"], theta)
    return direct + reflectivity * accept * np.clip(through - direct, 0.0, None)
