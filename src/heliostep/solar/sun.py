"""The sun and the plant: site, receiver line, sun position (NREL SPA through pvlib), sun vector,
sunrise/transit/sunset.

Conventions: see :mod:`heliostep.solar`.
"""

from __future__ import annotations

import dataclasses
import datetime as dt
import functools

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
from heliostep.solar.sun_cache import cached_frame

#: Compass direction of the plant's +y axis for each orientation [deg].
ORIENTATIONS = {"NS": 0.0, "EW": 90.0}


# --------------------------------------------------------------------------- site, plant
#: Site altitudes taken [m]: land on Earth (the Dead Sea's shore at -430 m, Everest at 8849 m), with
#: room; pvlib's pressure from altitude turns negative (complex angles) above 44.3 km.
ALTITUDE_RANGE = (-500.0, 9000.0)


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
        object.__setattr__(self, "latitude", check_range(self.latitude, "latitude", -90.0, 90.0, "deg"))
        object.__setattr__(self, "longitude", check_range(self.longitude, "longitude", -180.0, 180.0, "deg"))
        low, high = ALTITUDE_RANGE
        object.__setattr__(self, "altitude", check_range(self.altitude, "altitude", low, high, "m"))
        check_timezone(self.timezone)


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
        object.__setattr__(self, "tube_height", check_positive(self.tube_height, "tube_height", "m"))
        orientation = self.orientation.upper() if isinstance(self.orientation, str) else self.orientation
        if orientation not in ORIENTATIONS:
            raise InputError(f"orientation must be one of {', '.join(ORIENTATIONS)}, got {self.orientation!r}")
        object.__setattr__(self, "orientation", orientation)
        object.__setattr__(self, "azimuth_offset", check_finite_scalar(self.azimuth_offset, "azimuth_offset", " [deg]"))

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
    offset = check_finite_scalar(azimuth_offset, "azimuth_offset", " [deg]")
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
        angles in degrees. The geometry below uses ``apparent_elevation``. Kept by content
        (:mod:`heliostep.solar.sun_cache`): the same grid again is read back, pvlib not imported.
    """
    times = check_times(times)
    latitude = check_range(latitude, "latitude", -90.0, 90.0, "deg")
    longitude = check_range(longitude, "longitude", -180.0, 180.0, "deg")
    altitude = check_finite_scalar(altitude, "altitude", " [m]")
    if pressure is not None:
        pressure = check_positive(pressure, "pressure", "Pa")
    temperature = check_finite_scalar(temperature, "temperature", " [degC]")
    delta_t = check_finite_scalar(delta_t, "delta_t", " [s]")

    arguments = (times, latitude, longitude, altitude, pressure, temperature, delta_t)
    parameters = ("nrel_numpy", latitude, longitude, altitude, "none" if pressure is None else pressure)
    compute = functools.partial(_pvlib_solar_position, *arguments)
    return cached_frame("solar_position", times, (*parameters, temperature, delta_t), compute)


def _pvlib_solar_position(times, latitude, longitude, altitude, pressure, temperature, delta_t) -> pd.DataFrame:
    """pvlib's SPA (``nrel_numpy``), the inputs checked (:func:`solar_position`)."""
    # imported here, not at the top: pvlib's __init__ imports all of pvlib (scipy.integrate, h5py, requests)
    import pvlib.solarposition

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
    template = series_template(elevation, azimuth)
    altitude = np.radians(as_float_array(elevation))
    relative_azimuth = np.radians(as_float_array(azimuth) - plant_azimuth)
    sun_x = np.cos(altitude) * np.sin(relative_azimuth)  # xS = cos(alpha) sin(a)
    sun_y = np.cos(altitude) * np.cos(relative_azimuth)  # yS = cos(alpha) cos(a)
    sun_z = np.sin(altitude) * np.ones_like(relative_azimuth)  # zS = sin(alpha)
    return (
        wrap_like(sun_x, template, "sun_x"),
        wrap_like(sun_y, template, "sun_y"),
        wrap_like(sun_z, template, "sun_z"),
    )


def sun_events(date, site: Site) -> dict[str, pd.Timestamp | None]:
    """Sunrise, solar transit and sunset of one local calendar day (NREL SPA).

    Parameters
    ----------
    date : datetime.date
        Local calendar date at the site.
    site : Site

    Returns
    -------
    dict
        ``"sunrise"``, ``"transit"``, ``"sunset"``: timezone-aware timestamps in the site's
        timezone, ``None`` where the sun does not rise or set that day (polar day or night).
    """
    instants = _sun_event_instants(date, site.latitude, site.longitude, site.timezone)
    return {
        column: None if value is None else pd.Timestamp(value, tz="UTC").tz_convert(site.timezone)
        for column, value in zip(_SUN_EVENTS, instants)
    }


_SUN_EVENTS = ("sunrise", "transit", "sunset")


@functools.lru_cache(maxsize=4096)
def _sun_event_instants(date, latitude: float, longitude: float, timezone: str) -> tuple[int | None, ...]:
    """:func:`sun_events`' instants as int64 ns since the epoch (UTC), None where there is none; kept
    per process too, since a sweep validates the same few hundred dates for thousands of cases."""
    noon = pd.DatetimeIndex([pd.Timestamp(dt.datetime.combine(date, dt.time(12)))]).tz_localize(timezone)

    def compute() -> pd.DataFrame:  # NaT's value where none
        import pvlib.solarposition  # (see solar_position)

        events = pvlib.solarposition.sun_rise_set_transit_spa(noon, latitude, longitude)
        stamps = [events[column].iloc[0] for column in _SUN_EVENTS]
        values = {c: [pd.NaT.value if pd.isna(s) else pd.Timestamp(s).value] for c, s in zip(_SUN_EVENTS, stamps)}
        return pd.DataFrame(values, index=noon)

    events = cached_frame("sun_events", noon, ("spa", latitude, longitude), compute)
    values = (int(events[column].iloc[0]) for column in _SUN_EVENTS)
    return tuple(None if value == pd.NaT.value else value for value in values)
