"""Tracking laws: the single-axis tilt and end loss, the two-axis mirror, the reference panel angle.

Conventions: see :mod:`heliostep.solar`.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from heliostep.errors import InputError
from heliostep.solar.checks import (
    as_float_array,
    check_finite_scalar,
    check_positive,
    check_range,
    check_times,
    check_timezone,
    series_template,
    wrap_like,
)
from heliostep.solar.sun import Plant, Site, solar_position, sun_vector

#: The driven axis of a two-axis end mirror.
AXES = ("secondary", "primary")
#: What a reference angle does while the sun is down.
STOW_POLICIES = ("hold", "stow")


# --------------------------------------------------------------------------- single-axis mirror
def single_axis_tilt(elevation, azimuth, mirror_distance, tube_height, plant_azimuth: float = 0.0):
    """Angle beta of a classic (single-axis) mirror's normal from the plant's +x axis.

    The normal lies in the x-z plane and bisects the sun direction projected on that
    plane and the direction from the mirror to the tube. For a horizontal mirror
    beta = pi/2; beta > pi/2 tilts the normal toward -x (West for a North-South plant).

    Parameters
    ----------
    elevation, azimuth : array-like or Series  [deg]
        Apparent sun elevation; azimuth from North toward East.
    mirror_distance : float or array-like  [m]
        Transverse position d of the mirror (x = d).
    tube_height : float  [m]
        Height h of the tube above the mirror plane, > 0.
    plant_azimuth : float, default 0  [deg]

    Returns
    -------
    array or Series  [rad]
        beta, within (0, pi) while the sun is above the horizon.
    """
    tube_height = check_positive(tube_height, "tube_height", "m")
    distance = as_float_array(mirror_distance)
    sun_x, _, sun_z = sun_vector(as_float_array(elevation), as_float_array(azimuth), plant_azimuth)
    sun_direction = np.arctan2(sun_z, sun_x)  # projected sun on x-z, from +x
    tube_direction = np.arctan2(tube_height, -distance)  # T = (-d, h) / sqrt(d^2 + h^2)
    beta = 0.5 * (sun_direction + tube_direction)  # [paper], eq. 1
    return wrap_like(beta, series_template(elevation, azimuth, mirror_distance), "single_axis_tilt")


def end_loss_length(elevation, azimuth, mirror_distance, tube_height, plant_azimuth: float = 0.0):
    """Longitudinal shift k of the light a single-axis mirror sends onto the tube.

    A mirror whose normal has no y component keeps the y component of the light, so
    the reflected ray travels -yS along y while covering sqrt(d^2 + h^2) across.

    Parameters
    ----------
    elevation, azimuth : array-like or Series  [deg]
        Apparent sun elevation; azimuth from North toward East.
    mirror_distance : float or array-like  [m]
    tube_height : float  [m]
    plant_azimuth : float, default 0  [deg]

    Returns
    -------
    array or Series  [m]
        Signed k: positive means the light lands shifted toward +y, so the first |k|
        metres of the tube at the -y end are dark (at the +y end when k < 0).
        Infinite when the sun lies exactly along the tube.
    """
    tube_height = check_positive(tube_height, "tube_height", "m")
    distance = as_float_array(mirror_distance)
    _, sun_y, _ = sun_vector(as_float_array(elevation), as_float_array(azimuth), plant_azimuth)
    with np.errstate(divide="ignore"):
        # |k| as in eq. 2 (cos(alpha) cos(a) = yS); the light travels -yS along y, hence the sign
        shift = -sun_y / np.sqrt(1.0 - sun_y**2) * np.hypot(distance, tube_height)  # [paper], eq. 2
    return wrap_like(shift, series_template(elevation, azimuth, mirror_distance), "end_loss_length")


# --------------------------------------------------------------------------- two-axis mirror
def two_axis_normal(sun_x, sun_y, sun_z, mirror_distance, tube_height):
    """Normal of a two-axis mirror sending the sun to the tube point in its cross-section.

    Parameters
    ----------
    sun_x, sun_y, sun_z : array-like or Series  [-]
        Unit sun vector in the plant frame (:func:`sun_vector`).
    mirror_distance : float or array-like  [m]
    tube_height : float  [m]

    Returns
    -------
    normal_x, normal_y, normal_z : arrays or Series  [-]
        n = (S + T) / |S + T| with T = (-d, 0, h) / sqrt(d^2 + h^2); NaN if S = -T.
    """
    tube_height = check_positive(tube_height, "tube_height", "m")
    distance = as_float_array(mirror_distance)
    slant = np.hypot(distance, tube_height)
    target_x, target_z = -distance / slant, tube_height / slant  # T, unit vector to the tube
    sum_x = as_float_array(sun_x) + target_x
    sum_y = as_float_array(sun_y) + 0.0
    sum_z = as_float_array(sun_z) + target_z
    norm = np.sqrt(sum_x**2 + sum_y**2 + sum_z**2)
    with np.errstate(invalid="ignore", divide="ignore"):
        normal = [component / norm for component in (sum_x, sum_y, sum_z)]  # n = (S+T)/|S+T|
    template = series_template(sun_x, sun_y, sun_z, mirror_distance)
    return tuple(wrap_like(c, template, name) for c, name in zip(normal, ("normal_x", "normal_y", "normal_z")))


def normal_orientation(normal_x, normal_y, normal_z):
    """Azimuth and altitude of a mirror normal in the plant frame.

    Parameters
    ----------
    normal_x, normal_y, normal_z : array-like or Series  [-]
        Unit normal in the plant frame.

    Returns
    -------
    normal_azimuth : array or Series  [rad]
        From +y toward +x, within [0, 2 pi).
    normal_altitude : array or Series  [rad]
        Above the x-y plane.
    """
    x, y, z = (as_float_array(c) for c in (normal_x, normal_y, normal_z))
    normal_azimuth = np.mod(np.arctan2(x, y), 2.0 * np.pi)  # [paper], eq. 5
    normal_altitude = np.arctan2(z, np.hypot(x, y))  # [paper], eq. 6
    template = series_template(normal_x, normal_y, normal_z)
    return wrap_like(normal_azimuth, template, "normal_azimuth"), wrap_like(
        normal_altitude, template, "normal_altitude"
    )


def two_axis_angles_from_normal(normal_x, normal_y, normal_z):
    """Primary and secondary rotation angles that give a normal.

    n = R_y(primary) R_x(secondary) z_hat = (cos q sin p, -sin q, cos q cos p).

    Parameters
    ----------
    normal_x, normal_y, normal_z : array-like or Series  [-]

    Returns
    -------
    primary : array or Series  [rad]
        About the plant's y axis, right-hand rule: positive tilts the normal toward +x.
        Minus the paper's eq. 3 sign.
    secondary : array or Series  [rad]
        About the x axis carried by the primary, right-hand rule: positive tilts the
        normal toward -y.
    """
    template = series_template(normal_x, normal_y, normal_z)
    azimuth, altitude = normal_orientation(as_float_array(normal_x), as_float_array(normal_y), as_float_array(normal_z))
    # tan(p) = sin(az) / tan(alt): the paper's eq. 3 without its minus sign (our sign convention)
    primary = np.arctan2(np.sin(azimuth) * np.cos(altitude), np.sin(altitude))  # [paper], eq. 3
    # q = -arcsin(cos(alt) cos(az)), written as an arctan2 to stay exact near +-90 deg
    along = np.cos(altitude) * np.cos(azimuth)
    across = np.hypot(np.cos(altitude) * np.sin(azimuth), np.sin(altitude))
    secondary = -np.arctan2(along, across)  # [paper], eq. 4
    return wrap_like(primary, template, "primary"), wrap_like(secondary, template, "secondary")


def two_axis_angles(elevation, azimuth, mirror_distance, tube_height, plant_azimuth: float = 0.0):
    """Primary and secondary angles of a two-axis mirror tracking the sun onto the tube.

    Parameters
    ----------
    elevation, azimuth : array-like or Series  [deg]
        Apparent sun elevation; azimuth from North toward East.
    mirror_distance : float or array-like  [m]
    tube_height : float  [m]
    plant_azimuth : float, default 0  [deg]

    Returns
    -------
    primary, secondary : arrays or Series  [rad]
        See :func:`two_axis_angles_from_normal` for the sign conventions.
    """
    template = series_template(elevation, azimuth, mirror_distance)
    sun_x, sun_y, sun_z = sun_vector(as_float_array(elevation), as_float_array(azimuth), plant_azimuth)
    normal = two_axis_normal(
        sun_x, sun_y, sun_z, mirror_distance=as_float_array(mirror_distance), tube_height=tube_height
    )
    primary, secondary = two_axis_angles_from_normal(*normal)
    return wrap_like(primary, template, "primary"), wrap_like(secondary, template, "secondary")


# --------------------------------------------------------------------------- reference angle
def time_window(start, end, freq="1s", timezone: str | None = None) -> pd.DatetimeIndex:
    """Sample times from ``start`` to ``end`` inclusive.

    Parameters
    ----------
    start, end : str or pandas.Timestamp
        Naive values are read in ``timezone``.
    freq : str or pandas.Timedelta, default "1s"
        Sampling step.
    timezone : str, optional
        IANA name; required when ``start`` or ``end`` is naive.

    Returns
    -------
    pandas.DatetimeIndex
    """
    if timezone is not None:
        check_timezone(timezone)
    stamps = []
    for name, value in (("start", start), ("end", end)):
        try:
            stamp = pd.Timestamp(value)
        except (TypeError, ValueError) as exc:
            raise InputError(f"{name} is not a date/time: {value!r}") from exc
        if stamp is pd.NaT:
            raise InputError(f"{name} is not a date/time: {value!r}")
        if stamp.tzinfo is None:
            if timezone is None:
                raise InputError(f"{name} is naive (no timezone); give a timezone")
            stamp = stamp.tz_localize(timezone)
        stamps.append(stamp)
    start_stamp, end_stamp = stamps
    if end_stamp <= start_stamp:
        raise InputError(f"empty window: end ({end_stamp}) must be after start ({start_stamp})")
    try:
        times = pd.date_range(start_stamp, end_stamp, freq=freq)
    except ValueError as exc:
        raise InputError(f"freq {freq!r} is not a pandas frequency") from exc
    if timezone is not None:
        times = times.tz_convert(timezone)
    return times


def panel_angle_reference(
    times,
    site: Site,
    plant: Plant,
    mirror_distance: float,
    axis: str = "secondary",
    stow: str = "hold",
    stow_angle: float = 0.0,
    min_elevation: float = 0.0,
) -> pd.Series:
    """Reference angle of one two-axis mirror's panel, the law its motor follows.

    Parameters
    ----------
    times : pandas.DatetimeIndex
        Timezone-aware, not empty.
    site : Site
    plant : Plant
    mirror_distance : float  [m]
        Transverse position d; all primaries of the field follow the central
        mirror (d = 0).
    axis : {"secondary", "primary"}, default "secondary"
    stow : {"hold", "stow"}, default "hold"
        Policy while the sun is at or below ``min_elevation``: "hold" keeps the last
        valid angle (before the first valid sample, the first valid one; if no sample
        is valid, ``stow_angle``), "stow" goes to ``stow_angle``.
    stow_angle : float, default 0  [rad]
    min_elevation : float, default 0  [deg]
        Apparent sun elevation above which the mirror tracks.

    Returns
    -------
    pandas.Series  [rad]
        Named ``panel_angle_ref``, indexed by ``times``; never NaN.
    """
    times = check_times(times)
    if not isinstance(site, Site):
        raise InputError(f"site must be a heliostep.solar.Site, got {type(site).__name__}")
    if not isinstance(plant, Plant):
        raise InputError(f"plant must be a heliostep.solar.Plant, got {type(plant).__name__}")
    if axis not in AXES:
        raise InputError(f"axis must be one of {', '.join(AXES)}, got {axis!r}")
    if stow not in STOW_POLICIES:
        raise InputError(f"stow must be one of {', '.join(STOW_POLICIES)}, got {stow!r}")
    mirror_distance = check_finite_scalar(mirror_distance, "mirror_distance", " [m]")
    stow_angle = check_range(stow_angle, "stow_angle", -np.pi / 2, np.pi / 2, "rad")
    min_elevation = check_range(min_elevation, "min_elevation", -90.0, 90.0, "deg")

    position = solar_position(times, site.latitude, site.longitude, site.altitude)
    elevation = position["apparent_elevation"].to_numpy()
    primary, secondary = two_axis_angles(
        elevation, position["azimuth"].to_numpy(), mirror_distance, plant.tube_height, plant.azimuth
    )
    angle = pd.Series(secondary if axis == "secondary" else primary, index=times, name="panel_angle_ref")
    valid = (elevation > min_elevation) & np.isfinite(angle.to_numpy())
    if stow == "stow":
        return angle.where(valid, stow_angle)
    held = angle.where(valid).ffill().bfill()
    return held.fillna(stow_angle)
