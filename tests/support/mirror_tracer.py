"""A Monte Carlo ray tracer of a field of flat mirrors for the tests, sharing no code with ``heliostep.solar``.

The sun from pvlib (SPA); mirrors as rectangles turned by rotation matrices R_y(p) R_x(q) (local z
their normal, local x their width across the tube, local y their length along it); the tracking
normals from the law of reflection (the bisector of the sun and the direction to the tube); rays from
points sampled uniformly over a mirror, toward the sun (shading) and along the reflected ray
(blocking), intersected with every other mirror's plane and tested inside its rectangle.
Frame: x East (across the tube), y North (along it), z up; pivots at z = 0, the tube at z = h over x = 0.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import pvlib

LAT, LON, TZ = 40.0, 14.25, "Europe/Rome"
N_ROWS = 13
#: Monte Carlo points per mirror; the standard error of a fraction f is sqrt(f (1 - f) / M) <= 0.0025.
M_POINTS = 40_000


def sun_vectors(stamps):
    times = pd.DatetimeIndex([pd.Timestamp(s, tz=TZ) for s in stamps])
    sun = pvlib.solarposition.get_solarposition(times, LAT, LON, 0.0, method="nrel_numpy")
    a, z = np.radians(sun["apparent_elevation"].to_numpy()), np.radians(sun["azimuth"].to_numpy())
    return np.stack([np.cos(a) * np.sin(z), np.cos(a) * np.cos(z), np.sin(a)], axis=-1)  # x East, y North, z up


def tracking_normals(sun, distances, h, two_axis):
    """Tracking normals, from the law of reflection: the normal bisects the sun and the tube direction."""
    to_tube = np.stack([-distances, 0 * distances, np.full_like(distances, h)], axis=-1)
    to_tube = to_tube / np.linalg.norm(to_tube, axis=-1, keepdims=True)
    incoming = sun if two_axis else sun * np.array([1.0, 0.0, 1.0])  # single axis: the sun in the cross-section
    incoming = incoming / np.linalg.norm(incoming, axis=-1, keepdims=True)
    bisector = incoming[:, None, :] + to_tube[None, :, :]
    return bisector / np.linalg.norm(bisector, axis=-1, keepdims=True)


def rectangle(normal):
    """Rotation of a mirror whose local z is its normal: R = R_y(p) R_x(q), p = atan2(nx, nz), q = -asin(ny)."""
    p, q = np.arctan2(normal[0], normal[2]), -np.arcsin(np.clip(normal[1], -1, 1))
    r_y = np.array([[np.cos(p), 0, np.sin(p)], [0, 1, 0], [-np.sin(p), 0, np.cos(p)]])
    r_x = np.array([[1, 0, 0], [0, np.cos(q), -np.sin(q)], [0, np.sin(q), np.cos(q)]])
    return r_y @ r_x  # columns: width axis, length axis, normal


def receiver_hit(points, direction, h, radius):
    """Whether each ray points + lambda direction (lambda > 0) passes within ``radius`` of the receiver's axis,
    the line (0, y, h) along y: the closest approach of two lines in 3-D (the parameters that make the
    connecting segment perpendicular to both)."""
    w0 = points - np.array([0.0, 0.0, h])
    axis = np.array([0.0, 1.0, 0.0])
    b, d, e = direction @ axis, np.sum(w0 * direction, axis=1), w0 @ axis
    denominator = 1.0 - b * b  # |direction| = |axis| = 1
    lam = (b * e - d) / denominator
    mu = (e - b * d) / denominator
    gap = w0 + lam[:, None] * direction - mu[:, None] * axis
    return (lam > 0) & (np.linalg.norm(gap, axis=1) <= radius)


def trace(sun, normals, centres, target, width, length, h, rng, focal_length=None, receiver_radius=None):
    """Fractions of mirror ``target``'s area whose sun ray is stopped by another mirror (shaded), whose
    reflected ray is (blocked), and either (lost). ``focal_length``: the target curved about its long axis
    (a parabolic cylinder z = u^2 / (4 f): the local normal tilts by atan(u / (2 f)) across its width;
    its sag, w^2 / (16 f), a few mm, neglected); None: flat. ``receiver_radius``: the receiver, a cylinder
    of that radius about (0, y, h), stops sun rays too (its own shadow); None: it casts none."""
    frames = np.array([rectangle(n) for n in normals])  # (K, 3, 3)
    uv = rng.uniform(-0.5, 0.5, size=(M_POINTS, 2)) * np.array([width, min(length, 2.0)])
    points = centres[target] + uv[:, :1] * frames[target][:, 0] + uv[:, 1:] * frames[target][:, 1]
    n_t = np.broadcast_to(frames[target][:, 2], points.shape)
    if focal_length is not None:
        n_t = n_t - (uv[:, :1] / (2 * focal_length)) * frames[target][:, 0]  # the surface's slope du / (2 f)
        n_t = n_t / np.linalg.norm(n_t, axis=1, keepdims=True)
    reflected = 2 * (n_t @ sun)[:, None] * n_t - sun  # law of reflection, the ray going up toward the tube
    stopped = []
    for direction in (sun, reflected):
        hit = np.zeros(M_POINTS, dtype=bool)
        for k in range(len(centres)):
            if k == target:
                continue
            u_k, v_k, n_k = frames[k][:, 0], frames[k][:, 1], frames[k][:, 2]
            with np.errstate(divide="ignore", invalid="ignore"):
                t = ((centres[k] - points) @ n_k) / (direction @ n_k)
            at = points + t[:, None] * direction - centres[k]
            inside = (np.abs(at @ u_k) <= width / 2) & (np.abs(at @ v_k) <= length / 2)
            below_tube = (points[:, 2] + t * direction[..., 2]) < h
            hit |= (t > 0) & inside & below_tube
        if receiver_radius is not None and direction is sun:
            hit |= receiver_hit(points, np.broadcast_to(sun, points.shape), h, receiver_radius)
        stopped.append(hit)
    return stopped[0].mean(), stopped[1].mean(), (stopped[0] | stopped[1]).mean()


def layout(spacing, along=None, n_along=5):
    distances = (np.arange(N_ROWS) - N_ROWS // 2) * spacing
    if along is None:
        return distances, np.stack([distances, 0 * distances, 0 * distances], axis=-1), None
    ys = (np.arange(n_along) - n_along // 2) * along
    grid = np.array([(d, y, 0.0) for y in ys for d in distances])  # row-major: along index, then row
    return distances, grid, ys
