"""Direct normal irradiance (DNI) over a window: pvlib's clear sky, or a TMY3/EPW weather file.

Clear sky: pvlib's Ineichen-Perez model (``Location.get_clearsky(model="ineichen")``) with the
Linke turbidity climatology shipped inside pvlib (no download). Weather files: pvlib.iotools
``read_epw`` / ``read_tmy3``; a typical-year file mixes years, so its hourly DNI is matched to
the window by month, day and hour of the site's standard time and interpolated linearly.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from heliostep.errors import InputError
from heliostep.solar.checks import check_positive, check_times
from heliostep.solar.sun import Site

#: Largest latitude/longitude difference between a weather file's header and the site [deg].
MAX_SITE_OFFSET = 1.0


def clear_sky_dni(times, site: Site, sun: pd.DataFrame | None = None) -> pd.Series:
    """Clear-sky DNI at the site (Ineichen & Perez 2002, as implemented by pvlib).

    Parameters
    ----------
    times : pandas.DatetimeIndex
        Timezone-aware.
    site : Site
    sun : pandas.DataFrame, optional
        :func:`heliostep.solar.solar_position` at ``times`` already computed (its
        ``apparent_zenith`` is what the model takes); computed here when not given.

    Returns
    -------
    pandas.Series  [W/m^2]
        Named ``dni``, indexed by ``times``; 0 while the sun is down.
    """
    import pvlib

    times = check_times(times)
    location = pvlib.location.Location(site.latitude, site.longitude, site.timezone, site.altitude)
    with warnings.catch_warnings():  # pvlib's pandas deprecations are not ours to fix
        warnings.simplefilter("ignore")
        sky = location.get_clearsky(times, model="ineichen", solar_position=sun)  # Ineichen & Perez (2002), pvlib
    return sky["dni"].fillna(0.0).clip(lower=0.0).rename("dni")


def read_weather(path, site: Site, max_offset: float = MAX_SITE_OFFSET) -> pd.Series:
    """Hourly DNI of a TMY3 (``.csv``) or EPW (``.epw``) file for the site.

    Parameters
    ----------
    path : str or pathlib.Path
    site : Site
        The file's header latitude and longitude must be within ``max_offset`` of it.
    max_offset : float, default MAX_SITE_OFFSET  [deg]

    Returns
    -------
    pandas.Series  [W/m^2]
        Named ``dni``, indexed by the file's timestamps.

    Raises
    ------
    InputError
        Naming the file and the key (``weather_file``, ``latitude``, ``longitude``, ``dni``).
    """
    import pvlib

    max_offset = check_positive(max_offset, "max_offset", "deg")
    path = Path(path)
    reader = pvlib.iotools.read_epw if path.suffix.lower() == ".epw" else pvlib.iotools.read_tmy3
    try:
        kwargs = {} if reader is pvlib.iotools.read_epw else {"map_variables": True}
        data, meta = reader(str(path), **kwargs)
    except Exception as exc:
        raise InputError(f"weather_file {path}: cannot read it as {path.suffix or 'TMY3'} ({exc})") from exc
    for key, expected in (("latitude", site.latitude), ("longitude", site.longitude)):
        value = meta.get(key)
        try:
            value = float(value)
        except (TypeError, ValueError):
            raise InputError(f"weather_file {path}: {key} missing from the header") from None
        if abs(value - expected) > max_offset:
            raise InputError(
                f"weather_file {path}: {key} {value:g} deg is more than {max_offset:g} deg "
                f"from the site's {expected:g} deg"
            )
    column = "dni" if "dni" in data else "DNI" if "DNI" in data else None
    if column is None:
        raise InputError(f"weather_file {path}: no dni column")
    dni = pd.to_numeric(data[column], errors="coerce")
    if dni.isna().any() or (dni < 0).any():
        raise InputError(f"weather_file {path}: dni has missing or negative values")
    return dni.rename("dni")


@dataclass(frozen=True)
class WeatherDNI:
    """A typical-year weather file's hourly DNI, read once (:meth:`read`), evaluated at any
    times of the year (:meth:`at`): matched by month, day and hour of the file's standard time
    and interpolated linearly."""

    path: Path
    table: pd.Series  # DNI [W/m^2] by (month * 100 + day) * 100 + hour
    timezone: object  # the file's timezone (None: naive local time)

    @classmethod
    def read(cls, path, site: Site, max_offset: float = MAX_SITE_OFFSET) -> WeatherDNI:
        """The file's DNI (:func:`read_weather`: raises InputError naming file and key)."""
        hourly = read_weather(path, site, max_offset)
        stamps = hourly.index
        hour_key = (stamps.month * 100 + stamps.day) * 100 + stamps.hour  # typical year: ignore the year
        table = pd.Series(hourly.to_numpy(), index=hour_key).groupby(level=0).mean()
        return cls(Path(path), table, stamps.tz)

    def at(self, times) -> pd.Series:
        """DNI [W/m^2] at ``times`` (timezone-aware), named ``dni``; InputError (key ``window``)
        when the file does not cover them."""
        times = check_times(times)
        local = times.tz_convert(self.timezone) if self.timezone is not None else times.tz_localize(None)
        floor = local.floor("h")
        fraction = ((local - floor) / pd.Timedelta(hours=1)).to_numpy()
        values = []
        for stamp in (floor, floor + pd.Timedelta(hours=1)):
            key = (stamp.month * 100 + stamp.day) * 100 + stamp.hour
            values.append(self.table.reindex(key).to_numpy())
        if np.isnan(values[0]).any() or np.isnan(values[1][fraction > 0]).any():
            raise InputError(
                f"weather_file {self.path}: does not cover the window {times[0]} - {times[-1]} (key: window)"
            )
        low, high = values[0], np.where(fraction > 0, values[1], values[0])
        return pd.Series(low + fraction * (high - low), index=times, name="dni")


def weather_dni(times, site: Site, path, max_offset: float = MAX_SITE_OFFSET) -> pd.Series:
    """DNI of a typical-year file at the window's times (matched by month, day and hour).

    Parameters
    ----------
    times : pandas.DatetimeIndex
        Timezone-aware.
    site : Site
    path : str or pathlib.Path
    max_offset : float  [deg]

    Returns
    -------
    pandas.Series  [W/m^2]
        Named ``dni``, indexed by ``times`` (:meth:`WeatherDNI.at` of the file read once).
    """
    return WeatherDNI.read(path, site, max_offset).at(times)


def dni(times, site: Site, weather_file=None, sun: pd.DataFrame | None = None) -> pd.Series:
    """DNI over a window: clear sky unless a weather file (a path, or a :class:`WeatherDNI`
    already read) is given; ``sun``: see :func:`clear_sky_dni`.

    Returns
    -------
    pandas.Series  [W/m^2]
    """
    if weather_file is None:
        return clear_sky_dni(times, site, sun)
    if isinstance(weather_file, WeatherDNI):
        return weather_file.at(times)
    return weather_dni(times, site, weather_file)
