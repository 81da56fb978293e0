"""Solar geometry of a linear Fresnel plant with two-axis end mirrors.

Small, pure, vectorised functions in the style of pvlib: angles of the sun in
degrees (as pvlib gives them), mirror and motor angles in radians, lengths in
metres. A :class:`pandas.Series` in gives Series out (functions returning several
components return a tuple of Series).

``[paper]`` in the comments is the source paper of the project's physics notes
(linear Fresnel plant, two-axis end mirrors, stepper drive); ``eq. N`` is its
equation number. See ``docs/geometry.md`` for the equations and conventions.

Frames and conventions
----------------------
* Plant frame: x across the tube, y along the tube, z up. For the default
  North-South plant x = East, y = North. The plant azimuth ``plant_azimuth`` is
  the compass direction of +y, measured from North toward East [deg]: 0 for a
  North-South plant, 90 for an East-West plant (+y = East, +x = South), plus any
  ``azimuth_offset``. The frame stays right-handed for every azimuth.
* The receiver tube is parallel to y, at height ``tube_height`` above the mirror
  plane, over x = 0; a mirror sits at x = ``mirror_distance``.
* Sun: unit vector S toward the sun from pvlib's SPA (``nrel_numpy``). The
  geometry uses the *apparent* (refraction-corrected) elevation throughout,
  because that is the direction from which the light actually arrives.
* End loss k: signed, **positive k means the reflected light lands shifted
  toward +y** (North for a North-South plant), so the first |k| metres at the
  -y end of the tube get no light when k > 0 (and at the +y end when k < 0).
  Its magnitude is [paper] eq. 2.
* Two-axis mirror: n = R_y(primary) R_x(secondary) z_hat, i.e.
  n = (cos q sin p, -sin q, cos q cos p). Both rotations follow the right-hand
  rule: a positive primary tilts the normal toward +x (East for a North-South
  plant), a positive secondary tilts it toward -y. The paper writes eq. 3 with a
  minus sign (its opposite sense for the primary); ours is minus the paper's.
* Stow policy for reference angles (sun at or below ``min_elevation``):
  ``"hold"`` keeps the last valid angle (before the first valid sample, the first
  valid one; with no valid sample in the window at all, ``stow_angle``);
  ``"stow"`` goes to ``stow_angle``. No NaN ever leaves
  :func:`panel_angle_reference`.
"""

from __future__ import annotations

import dataclasses
import math
import numbers
import zoneinfo

import numpy as np
import pandas as pd
import pvlib

from heliostep.errors import InputError

__all__ = [
    "DEFAULT_MIRROR_SPACING",
    "PAPER_LEVER_ARM",
    "PAPER_PINION_RADIUS",
    "Plant",
    "Site",
    "end_loss_length",
    "field_distances",
    "field_primary_errors",
    "normal_orientation",
    "panel_angle_from_rotor",
    "panel_angle_reference",
    "panel_speed_from_rotor_speed",
    "plant_azimuth",
    "rotor_angle_from_panel",
    "rotor_speed_from_panel_speed",
    "single_axis_tilt",
    "solar_position",
    "sun_vector",
    "time_window",
    "two_axis_angles",
    "two_axis_angles_from_normal",
    "two_axis_normal",
]

#: Pinion radius of the secondary drive in the paper [m].
PAPER_PINION_RADIUS = 2.5e-3
#: Lever arm of the panel on the rack in the paper [m].
PAPER_LEVER_ARM = 0.3
#: Transverse spacing of the 13 end mirrors [m]. Not from the paper: an assumption.
DEFAULT_MIRROR_SPACING = 0.6

ORIENTATIONS = {"NS": 0.0, "EW": 90.0}
AXES = ("secondary", "primary")
STOW_POLICIES = ("hold", "stow")


# --------------------------------------------------------------------------- helpers
def _check_finite_scalar(value, name: str, unit: str = "") -> float:
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise InputError(f"{name} must be a real number{unit}, got {value!r}")
    value = float(value)
    if not math.isfinite(value):
        raise InputError(f"{name} must be finite{unit}, got {value!r}")
    return value


def _check_range(value, name: str, low: float, high: float, unit: str) -> float:
    value = _check_finite_scalar(value, name, f" [{unit}]")
    if not low <= value <= high:
        raise InputError(f"{name} must be within [{low:g}, {high:g}] {unit}, got {value:g}")
    return value


def _check_positive(value, name: str, unit: str) -> float:
    value = _check_finite_scalar(value, name, f" [{unit}]")
    if value <= 0.0:
        raise InputError(f"{name} must be > 0 {unit}, got {value:g}")
    return value


def _check_timezone(timezone: str) -> str:
    if not isinstance(timezone, str) or not timezone:
        raise InputError(f"timezone must be an IANA name such as 'Europe/Rome', got {timezone!r}")
    try:
        zoneinfo.ZoneInfo(timezone)
    except (zoneinfo.ZoneInfoNotFoundError, ValueError) as exc:
        raise InputError(
            f"timezone {timezone!r} is unknown; use an IANA name such as 'Europe/Rome' or 'UTC'"
        ) from exc
    return timezone


def _check_times(times) -> pd.DatetimeIndex:
    if isinstance(times, pd.Series):
        times = times.index if isinstance(times.index, pd.DatetimeIndex) else pd.DatetimeIndex(times)
    elif not isinstance(times, pd.DatetimeIndex):
        try:
            times = pd.DatetimeIndex(times)
        except (TypeError, ValueError) as exc:
            raise InputError(f"times must be a timezone-aware pandas DatetimeIndex: {exc}") from exc
    if len(times) == 0:
        raise InputError("times must not be empty (the window holds no sample)")
    if times.tz is None:
        raise InputError(
            "times must be timezone-aware (naive timestamps are ambiguous); "
            "localize them, e.g. times.tz_localize('Europe/Rome')"
        )
    return times


def _template(*values):
    """The first pandas Series among ``values`` (its index labels the output), or None."""
    for value in values:
        if isinstance(value, pd.Series):
            return value
    return None


def _wrap(array, template, name=None):
    if template is None:
        return array
    return pd.Series(np.broadcast_to(array, template.shape), index=template.index, name=name)


def _as_float_array(value) -> np.ndarray:
    return np.asarray(value, dtype=float)


# --------------------------------------------------------------------------- site, plant
@dataclasses.dataclass(frozen=True, kw_only=True)
class Site:
    """Where the plant is.

    Parameters
    ----------
    latitude : float  [deg]
        Positive North, within [-90, 90].
    longitude : float  [deg]
        Positive East, within [-180, 180].
    altitude : float, default 0  [m]
        Height above sea level (sets the pressure for SPA's refraction).
    timezone : str, default ``"UTC"``
        IANA name, used to build local windows and to show local times.
    """

    latitude: float
    longitude: float
    altitude: float = 0.0
    timezone: str = "UTC"

    def __post_init__(self):
        object.__setattr__(self, "latitude", _check_range(self.latitude, "latitude", -90.0, 90.0, "deg"))
        object.__setattr__(
            self, "longitude", _check_range(self.longitude, "longitude", -180.0, 180.0, "deg")
        )
        object.__setattr__(self, "altitude", _check_finite_scalar(self.altitude, "altitude", " [m]"))
        _check_timezone(self.timezone)


@dataclasses.dataclass(frozen=True, kw_only=True)
class Plant:
    """The receiver line.

    Parameters
    ----------
    tube_height : float  [m]
        Height h of the receiver tube above the mirror plane, > 0.
    orientation : {"NS", "EW"}, default "NS"
        Direction of the tube: North-South (+y = North) or East-West (+y = East).
    azimuth_offset : float, default 0  [deg]
        Extra rotation of the tube axis, from North toward East.
    """

    tube_height: float
    orientation: str = "NS"
    azimuth_offset: float = 0.0

    def __post_init__(self):
        object.__setattr__(self, "tube_height", _check_positive(self.tube_height, "tube_height", "m"))
        orientation = self.orientation.upper() if isinstance(self.orientation, str) else self.orientation
        if orientation not in ORIENTATIONS:
            raise InputError(
                f"orientation must be one of {', '.join(ORIENTATIONS)}, got {self.orientation!r}"
            )
        object.__setattr__(self, "orientation", orientation)
        object.__setattr__(
            self, "azimuth_offset", _check_finite_scalar(self.azimuth_offset, "azimuth_offset", " [deg]")
        )

    @property
    def azimuth(self) -> float:
        """Compass direction of the plant's +y axis (the tube) [deg], see :func:`plant_azimuth`."""
        return plant_azimuth(self.orientation, self.azimuth_offset)


def plant_azimuth(orientation: str = "NS", azimuth_offset: float = 0.0) -> float:
    """Compass direction of the plant's +y axis.

    Parameters
    ----------
    orientation : {"NS", "EW"}
        "NS": +y = North (0 deg); "EW": the frame turned by 90 deg, +y = East, +x = South.
    azimuth_offset : float  [deg]
        Added rotation from North toward East.

    Returns
    -------
    float  [deg]
    """
    key = orientation.upper() if isinstance(orientation, str) else orientation
    if key not in ORIENTATIONS:
        raise InputError(f"orientation must be one of {', '.join(ORIENTATIONS)}, got {orientation!r}")
    offset = _check_finite_scalar(azimuth_offset, "azimuth_offset", " [deg]")
    return ORIENTATIONS[key] + offset


# --------------------------------------------------------------------------- sun
def solar_position(
    times,
    latitude: float,
    longitude: float,
    altitude: float = 0.0,
    *,
    pressure: float | None = None,
    temperature: float = 12.0,
    delta_t: float = 67.0,
) -> pd.DataFrame:
    """Sun position from NREL's SPA (pvlib ``nrel_numpy``).

    Parameters
    ----------
    times : pandas.DatetimeIndex
        Timezone-aware, not empty.
    latitude : float  [deg]
        Within [-90, 90], positive North.
    longitude : float  [deg]
        Within [-180, 180], positive East.
    altitude : float, default 0  [m]
    pressure : float, optional  [Pa]
        Defaults to the standard pressure at ``altitude``.
    temperature : float, default 12  [degC]
    delta_t : float, default 67  [s]
        TT - UT1, as pvlib's default.

    Returns
    -------
    pandas.DataFrame
        Indexed by ``times``: ``apparent_elevation``, ``elevation``, ``apparent_zenith``,
        ``zenith``, ``azimuth`` (from North toward East), ``equation_of_time`` [min];
        angles in degrees. The geometry below uses ``apparent_elevation``.
    """
    times = _check_times(times)
    latitude = _check_range(latitude, "latitude", -90.0, 90.0, "deg")
    longitude = _check_range(longitude, "longitude", -180.0, 180.0, "deg")
    altitude = _check_finite_scalar(altitude, "altitude", " [m]")
    if pressure is not None:
        pressure = _check_positive(pressure, "pressure", "Pa")
    temperature = _check_finite_scalar(temperature, "temperature", " [degC]")
    delta_t = _check_finite_scalar(delta_t, "delta_t", " [s]")
    return pvlib.solarposition.get_solarposition(
        times,
        latitude,
        longitude,
        altitude=altitude,
        pressure=pressure,
        method="nrel_numpy",
        temperature=temperature,
        delta_t=delta_t,
    )


def sun_vector(elevation, azimuth, plant_azimuth: float = 0.0):
    """Unit vector toward the sun in the plant frame.

    Parameters
    ----------
    elevation : array-like or Series  [deg]
        Sun elevation (use the apparent one).
    azimuth : array-like or Series  [deg]
        Sun azimuth from North toward East.
    plant_azimuth : float, default 0  [deg]
        Compass direction of the plant's +y axis (:func:`plant_azimuth`).

    Returns
    -------
    sun_x, sun_y, sun_z : arrays or Series  [-]
        Across the tube, along the tube, up.
    """
    template = _template(elevation, azimuth)
    altitude = np.radians(_as_float_array(elevation))
    relative_azimuth = np.radians(_as_float_array(azimuth) - plant_azimuth)
    sun_x = np.cos(altitude) * np.sin(relative_azimuth)  # xS = cos(alpha) sin(a)
    sun_y = np.cos(altitude) * np.cos(relative_azimuth)  # yS = cos(alpha) cos(a)
    sun_z = np.sin(altitude) * np.ones_like(relative_azimuth)  # zS = sin(alpha)
    return (
        _wrap(sun_x, template, "sun_x"),
        _wrap(sun_y, template, "sun_y"),
        _wrap(sun_z, template, "sun_z"),
    )


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
    tube_height = _check_positive(tube_height, "tube_height", "m")
    distance = _as_float_array(mirror_distance)
    sun_x, _, sun_z = sun_vector(_as_float_array(elevation), _as_float_array(azimuth), plant_azimuth)
    sun_direction = np.arctan2(sun_z, sun_x)  # projected sun on x-z, from +x
    tube_direction = np.arctan2(tube_height, -distance)  # T = (-d, h) / sqrt(d^2 + h^2)
    beta = 0.5 * (sun_direction + tube_direction)  # [paper], eq. 1
    return _wrap(beta, _template(elevation, azimuth, mirror_distance), "single_axis_tilt")


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
    tube_height = _check_positive(tube_height, "tube_height", "m")
    distance = _as_float_array(mirror_distance)
    _, sun_y, _ = sun_vector(_as_float_array(elevation), _as_float_array(azimuth), plant_azimuth)
    with np.errstate(divide="ignore"):
        # |k| as in eq. 2 (cos(alpha) cos(a) = yS); the light travels -yS along y, hence the sign
        shift = -sun_y / np.sqrt(1.0 - sun_y**2) * np.hypot(distance, tube_height)  # [paper], eq. 2
    return _wrap(shift, _template(elevation, azimuth, mirror_distance), "end_loss_length")


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
    tube_height = _check_positive(tube_height, "tube_height", "m")
    distance = _as_float_array(mirror_distance)
    slant = np.hypot(distance, tube_height)
    target_x, target_z = -distance / slant, tube_height / slant  # T, unit vector to the tube
    sum_x = _as_float_array(sun_x) + target_x
    sum_y = _as_float_array(sun_y) + 0.0
    sum_z = _as_float_array(sun_z) + target_z
    norm = np.sqrt(sum_x**2 + sum_y**2 + sum_z**2)
    with np.errstate(invalid="ignore", divide="ignore"):
        normal = [component / norm for component in (sum_x, sum_y, sum_z)]  # n = (S+T)/|S+T|
    template = _template(sun_x, sun_y, sun_z, mirror_distance)
    return tuple(_wrap(c, template, name) for c, name in zip(normal, ("normal_x", "normal_y", "normal_z")))


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
    x, y, z = (_as_float_array(c) for c in (normal_x, normal_y, normal_z))
    normal_azimuth = np.mod(np.arctan2(x, y), 2.0 * np.pi)  # [paper], eq. 5
    normal_altitude = np.arctan2(z, np.hypot(x, y))  # [paper], eq. 6
    template = _template(normal_x, normal_y, normal_z)
    return _wrap(normal_azimuth, template, "normal_azimuth"), _wrap(normal_altitude, template, "normal_altitude")


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
    template = _template(normal_x, normal_y, normal_z)
    azimuth, altitude = normal_orientation(
        _as_float_array(normal_x), _as_float_array(normal_y), _as_float_array(normal_z)
    )
    # tan(p) = sin(az) / tan(alt): the paper's eq. 3 without its minus sign (our sign convention)
    primary = np.arctan2(np.sin(azimuth) * np.cos(altitude), np.sin(altitude))  # [paper], eq. 3
    # q = -arcsin(cos(alt) cos(az)), written as an arctan2 to stay exact near +-90 deg
    along = np.cos(altitude) * np.cos(azimuth)
    across = np.hypot(np.cos(altitude) * np.sin(azimuth), np.sin(altitude))
    secondary = -np.arctan2(along, across)  # [paper], eq. 4
    return _wrap(primary, template, "primary"), _wrap(secondary, template, "secondary")


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
    template = _template(elevation, azimuth, mirror_distance)
    sun = sun_vector(_as_float_array(elevation), _as_float_array(azimuth), plant_azimuth)
    normal = two_axis_normal(*sun, mirror_distance=_as_float_array(mirror_distance), tube_height=tube_height)
    primary, secondary = two_axis_angles_from_normal(*normal)
    return _wrap(primary, template, "primary"), _wrap(secondary, template, "secondary")


# --------------------------------------------------------------------------- field of end mirrors
def field_distances(n_mirrors: int = 13, spacing: float = DEFAULT_MIRROR_SPACING) -> np.ndarray:
    """Transverse positions of the end mirrors, centred on the tube.

    Parameters
    ----------
    n_mirrors : int, default 13
        Odd, so that the central mirror (index (n - 1) / 2) sits under the tube.
    spacing : float, default :data:`DEFAULT_MIRROR_SPACING`  [m]
        > 0.

    Returns
    -------
    numpy.ndarray  [m]
        d_i = (i - (n - 1) / 2) * spacing, i = 0 .. n - 1.
    """
    if isinstance(n_mirrors, bool) or not isinstance(n_mirrors, numbers.Integral) or n_mirrors < 1:
        raise InputError(f"n_mirrors must be an odd integer >= 1, got {n_mirrors!r}")
    if n_mirrors % 2 == 0:
        raise InputError(f"n_mirrors must be odd (a central mirror at d = 0), got {n_mirrors}")
    spacing = _check_positive(spacing, "spacing", "m")
    distances = (np.arange(n_mirrors) - (n_mirrors - 1) // 2) * spacing
    return np.round(distances, 12)  # drop the 1e-16 noise of the product, for readable tables


def field_primary_errors(
    elevation, azimuth, tube_height, mirror_distances=None, plant_azimuth: float = 0.0,
    calibration=None,
) -> pd.DataFrame:
    """Primary-angle error of each end mirror when all follow the central mirror's law.

    One motor turns every primary by the same angle, so each mirror's primary is its mounting
    offset plus the central mirror's primary. With ``calibration`` the offsets are the ones
    that make every mirror exact when the sun stands there, and the error is the difference
    in *motion* since; without it the error is the plain difference of the angles (the offset
    included).

    Parameters
    ----------
    elevation, azimuth : array-like or Series  [deg]
    tube_height : float  [m]
    mirror_distances : array-like, optional  [m]
        Defaults to :func:`field_distances` ().
    plant_azimuth : float, default 0  [deg]
    calibration : (float, float), optional  [deg]
        Sun elevation and azimuth at which the mirrors are mounted exact (e.g. solar noon).

    Returns
    -------
    pandas.DataFrame  [rad]
        Own primary minus the central (d = 0) primary, minus the same at the calibration;
        one column per mirror distance, indexed like ``elevation`` (if a Series).
    """
    if mirror_distances is None:
        mirror_distances = field_distances()
    distances = _as_float_array(mirror_distances).ravel()
    elevation_values = np.atleast_1d(_as_float_array(elevation))
    azimuth_values = np.atleast_1d(_as_float_array(azimuth))

    def own_minus_central(sun_elevation, sun_azimuth):
        central, _ = two_axis_angles(sun_elevation, sun_azimuth, 0.0, tube_height, plant_azimuth)
        own, _ = two_axis_angles(
            sun_elevation[:, None], sun_azimuth[:, None], distances[None, :], tube_height, plant_azimuth
        )
        return own - central[:, None]

    errors = own_minus_central(elevation_values, azimuth_values)
    if calibration is not None:
        offsets = own_minus_central(np.atleast_1d(float(calibration[0])), np.atleast_1d(float(calibration[1])))
        errors = errors - offsets
    template = _template(elevation, azimuth)
    index = template.index if template is not None else None
    return pd.DataFrame(
        errors,
        index=index,
        columns=pd.Index(distances, name="mirror_distance"),
    )


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
        _check_timezone(timezone)
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
    times = _check_times(times)
    if not isinstance(site, Site):
        raise InputError(f"site must be a heliostep.geometry.Site, got {type(site).__name__}")
    if not isinstance(plant, Plant):
        raise InputError(f"plant must be a heliostep.geometry.Plant, got {type(plant).__name__}")
    if axis not in AXES:
        raise InputError(f"axis must be one of {', '.join(AXES)}, got {axis!r}")
    if stow not in STOW_POLICIES:
        raise InputError(f"stow must be one of {', '.join(STOW_POLICIES)}, got {stow!r}")
    mirror_distance = _check_finite_scalar(mirror_distance, "mirror_distance", " [m]")
    stow_angle = _check_range(stow_angle, "stow_angle", -np.pi / 2, np.pi / 2, "rad")
    min_elevation = _check_range(min_elevation, "min_elevation", -90.0, 90.0, "deg")

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


# --------------------------------------------------------------------------- transmission
def _check_transmission(pinion_radius, lever_arm):
    return (
        _check_positive(pinion_radius, "pinion_radius", "m"),
        _check_positive(lever_arm, "lever_arm", "m"),
    )


def _check_panel_angle(values, name):
    array = _as_float_array(values)
    if not np.all(np.isfinite(array)) or np.any(np.abs(array) >= np.pi / 2):
        raise InputError(f"{name} must be finite and within (-pi/2, pi/2) rad")
    return array


def rotor_angle_from_panel(panel_angle, panel_angle0, pinion_radius, lever_arm, rotor_angle0=0.0):
    """Rotor angle of the secondary stepper that sets a panel angle (rack and pinion).

    Parameters
    ----------
    panel_angle : array-like or Series  [rad]
    panel_angle0 : float  [rad]
        Panel angle when the rotor is at ``rotor_angle0``.
    pinion_radius : float  [m]
        r, > 0 (paper: 2.5e-3).
    lever_arm : float  [m]
        s, > 0 (paper: 0.3).
    rotor_angle0 : float, default 0  [rad]

    Returns
    -------
    array or Series  [rad]
        theta = theta0 + (s / r) (tan(panel_angle) - tan(panel_angle0)).
    """
    radius, arm = _check_transmission(pinion_radius, lever_arm)
    panel = _check_panel_angle(panel_angle, "panel_angle")
    panel0 = _check_panel_angle(panel_angle0, "panel_angle0")
    rotor_angle0 = _as_float_array(rotor_angle0)
    # rack travel: r (theta - theta0)  # [paper], eq. 12
    # rack travel: s (tan(panel) - tan(panel0))  # [paper], eq. 13; equal, hence eq. 14:
    rotor = rotor_angle0 + arm / radius * (np.tan(panel) - np.tan(panel0))  # [paper], eq. 14
    return _wrap(rotor, _template(panel_angle), "rotor_angle")


def panel_angle_from_rotor(rotor_angle, panel_angle0, pinion_radius, lever_arm, rotor_angle0=0.0):
    """Panel angle set by a rotor angle of the secondary stepper (inverse of eq. 14).

    Parameters
    ----------
    rotor_angle : array-like or Series  [rad]
    panel_angle0 : float  [rad]
        Panel angle when the rotor is at ``rotor_angle0``.
    pinion_radius : float  [m]
    lever_arm : float  [m]
    rotor_angle0 : float, default 0  [rad]

    Returns
    -------
    array or Series  [rad]
        arctan(tan(panel_angle0) + (r / s) (theta - theta0)).
    """
    radius, arm = _check_transmission(pinion_radius, lever_arm)
    panel0 = _check_panel_angle(panel_angle0, "panel_angle0")
    rotor = _as_float_array(rotor_angle)
    panel = np.arctan(np.tan(panel0) + radius / arm * (rotor - _as_float_array(rotor_angle0)))  # [paper], eq. 14
    return _wrap(panel, _template(rotor_angle), "panel_angle")


def rotor_speed_from_panel_speed(panel_angle, panel_speed, pinion_radius, lever_arm):
    """Rotor speed of the secondary stepper for a panel speed.

    Parameters
    ----------
    panel_angle : array-like or Series  [rad]
    panel_speed : array-like or Series  [rad/s]
    pinion_radius, lever_arm : float  [m]

    Returns
    -------
    array or Series  [rad/s]
        omega = s omega_p / (r cos^2(panel_angle)).
    """
    radius, arm = _check_transmission(pinion_radius, lever_arm)
    panel = _check_panel_angle(panel_angle, "panel_angle")
    speed = arm * _as_float_array(panel_speed) / (radius * np.cos(panel) ** 2)  # [paper], eq. 15
    return _wrap(speed, _template(panel_angle, panel_speed), "rotor_speed")


def panel_speed_from_rotor_speed(panel_angle, rotor_speed, pinion_radius, lever_arm):
    """Panel speed for a rotor speed of the secondary stepper (inverse of eq. 15).

    Parameters
    ----------
    panel_angle : array-like or Series  [rad]
    rotor_speed : array-like or Series  [rad/s]
    pinion_radius, lever_arm : float  [m]

    Returns
    -------
    array or Series  [rad/s]
        omega_p = r omega cos^2(panel_angle) / s.
    """
    radius, arm = _check_transmission(pinion_radius, lever_arm)
    panel = _check_panel_angle(panel_angle, "panel_angle")
    speed = radius * _as_float_array(rotor_speed) * np.cos(panel) ** 2 / arm  # [paper], eq. 15
    return _wrap(speed, _template(panel_angle, rotor_speed), "panel_speed")
