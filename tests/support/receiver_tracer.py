"""A Monte Carlo ray tracer of one mirror and its receiver, written for the tests (vectorised numpy).

It shares no code with ``heliostep.solar``: the mirror's frame comes from rotation matrices, its
surface from the parabolic cylinder's equation, the receiver from circle and line intersections.

- Sun: rays uniform over a disc of half-angle 4.65 mrad about the sun's centre (a pillbox sun).
- Mirror: points uniform over a w x l rectangle centred at (d, 0, 0), its width along
  R_y(p) R_x(q) x_hat and its length along R_y(p) R_x(q) y_hat; flat, or the parabolic cylinder
  z' = s^2 / (4 f) about its long axis (exact surface point and normal).
- Slope error: the normal tilted by two independent Gaussian angles of sigma per axis of its
  tangent plane; specularity: the reflected ray tilted likewise.
- Each ray is weighted by the cosine of its incidence on its own normal, reflected
  (r = 2 (S.n) n - S) and tested against the receiver in the cross-section (x-z): the absorber, a
  circle of diameter D about (0, h); a secondary's aperture, the segment |x| <= a/2 of z = h - D/2,
  with the acceptance |atan(r_x / r_z)| <= theta_a. A ray that meets the absorber (through the
  aperture, with a secondary) counts 1; one accepted by the secondary that misses it counts rho_2.
Not traced: the receiver's own shadow on the mirror, neighbours, the glass envelope (a thin
shell that deviates no ray).
"""

from __future__ import annotations

import numpy as np

SUN_DISC = 4.65e-3  # [rad] the sun's half-angle (Rabl, Active Solar Collectors, 1985)


def rotation_y(angle):
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def rotation_x(angle):
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def _perpendiculars(vectors):
    """Two unit vectors perpendicular to each row of ``vectors`` (n, 3)."""
    helper = np.where(np.abs(vectors[:, [0]]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
    first = np.cross(vectors, helper)
    first /= np.linalg.norm(first, axis=1, keepdims=True)
    return first, np.cross(vectors, first)


def _tilt(vectors, sigma, rng):
    if sigma <= 0:
        return vectors
    e1, e2 = _perpendiculars(vectors)
    out = vectors + rng.normal(0.0, sigma, (len(vectors), 1)) * e1 + rng.normal(0.0, sigma, (len(vectors), 1)) * e2
    return out / np.linalg.norm(out, axis=1, keepdims=True)


def trace(
    sun,
    primary,
    secondary,
    distance,
    height,
    width,
    length,
    diameter,
    focal_length=None,
    slope_error=0.0,
    specularity=0.0,
    receiver_secondary=None,
    rays=400_000,
    seed=1,
):
    """Fraction of the mirror's reflected power that the receiver takes, and its standard error.

    ``receiver_secondary``: None or (aperture width [m], acceptance half-angle [rad], reflectivity).
    Returns (fraction, standard error) [-].
    """
    rng = np.random.default_rng(seed)
    frame = rotation_y(primary) @ rotation_x(secondary)
    across, along, normal = frame[:, 0], frame[:, 1], frame[:, 2]
    s = rng.uniform(-width / 2, width / 2, rays)[:, None]
    t = rng.uniform(-length / 2, length / 2, rays)[:, None]
    centre = np.array([distance, 0.0, 0.0])
    if focal_length is None:
        points = centre + s * across + t * along
        normals = np.repeat(normal[None, :], rays, axis=0)
    else:
        points = centre + s * across + t * along + s**2 / (4 * focal_length) * normal  # z' = s^2 / 4f
        normals = normal - s / (2 * focal_length) * across  # the gradient of z' - s^2 / 4f
        normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    normals = _tilt(normals, slope_error, rng)
    # sun rays uniform over the disc
    sun = np.asarray(sun, dtype=float) / np.linalg.norm(sun)
    e1, e2 = _perpendiculars(sun[None, :])
    radius, phi = SUN_DISC * np.sqrt(rng.uniform(0, 1, rays)), rng.uniform(0, 2 * np.pi, rays)
    to_sun = sun + np.tan(radius)[:, None] * (np.cos(phi)[:, None] * e1 + np.sin(phi)[:, None] * e2)
    to_sun /= np.linalg.norm(to_sun, axis=1, keepdims=True)
    cosine = np.sum(to_sun * normals, axis=1)
    weight = np.clip(cosine, 0.0, None)
    rays_out = _tilt(2 * cosine[:, None] * normals - to_sun, specularity, rng)  # law of reflection
    hits = _receiver(points, rays_out, height, diameter, receiver_secondary)
    total = weight.sum()
    fraction = float(np.sum(weight * hits) / total)
    error = float(np.sqrt(np.sum(weight**2 * (hits - fraction) ** 2)) / total)
    return fraction, error


def _meets_circle(points, rays, height, radius):
    """The ray's cross-section line enters the circle of ``radius`` about (0, height), ahead."""
    px, pz = points[:, 0], points[:, 2] - height
    rx, rz = rays[:, 0], rays[:, 2]
    a = rx**2 + rz**2
    b = 2 * (px * rx + pz * rz)
    c = px**2 + pz**2 - radius**2
    disc = b**2 - 4 * a * c
    with np.errstate(invalid="ignore"):
        far = (-b + np.sqrt(disc)) / (2 * a)
    return (disc >= 0) & (far > 0)


def _receiver(points, rays, height, diameter, receiver_secondary):
    absorber = _meets_circle(points, rays, height, diameter / 2)
    if receiver_secondary is None:
        return absorber.astype(float)
    aperture, acceptance, reflectivity = receiver_secondary
    plane = height - diameter / 2
    with np.errstate(invalid="ignore", divide="ignore"):
        ahead = (plane - points[:, 2]) / rays[:, 2]
        x = points[:, 0] + ahead * rays[:, 0]
    through = (ahead > 0) & (np.abs(x) <= aperture / 2)
    accepted = through & (np.abs(np.arctan2(rays[:, 0], rays[:, 2])) <= acceptance)
    direct = absorber & through
    return direct + reflectivity * (accepted & ~direct)
