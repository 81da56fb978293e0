"""Direct normal irradiance (DNI) and wind over a window: pvlib's clear sky, or a TMY3/EPW weather file.

A file's hourly energy is placed at the middle of its hour and interpolated linearly (it keeps the
day's energy and its centroid); its wind, measured at the stamps, is interpolated there.

Details: docs/light.md, ``heliostep.solar.irradiance``.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from heliostep.errors import InputError
from heliostep.input_files import MAX_WEATHER_BYTES, check_input_file
from heliostep.solar.checks import check_positive, check_times
from heliostep.solar.sun import Site
from heliostep.solar.sun_cache import cached_frame

#: Largest latitude/longitude difference between a weather file's header and the site [deg].
MAX_SITE_OFFSET = 1.0
#: Length of a TMY3/EPW record: hourly (TMY3 manual, EPW "number of records per hour" 1).
RECORD = pd.Timedelta(hours=1)
#: Where in its record a mean irradiance is placed: the middle of the hour ending at the stamp.
MID_RECORD = RECORD / 2
#: Wind speeds outside [0, this) are the files' missing-value codes (EPW 999, TMY3 -9900) [m/s].
MAX_WIND_SPEED = 999.0


#: The columns of a given sun position that pvlib's clear sky reads (``Location.get_clearsky`` and
#: ``get_airmass``: the apparent zenith or the zenith, by model; the apparent elevation).
_SUN_COLUMNS_READ = ("apparent_zenith", "zenith", "apparent_elevation")


def clear_sky_dni(times, site: Site, sun: pd.DataFrame | None = None) -> pd.Series:
    """Clear-sky DNI at the site (Ineichen & Perez 2002, as implemented by pvlib): the ``dni`` of
    :func:`clear_sky_irradiance`.

    Returns
    -------
    pandas.Series  [W/m^2]
        Named ``dni``, indexed by ``times``; 0 while the sun is down.
    """
    return clear_sky_irradiance(times, site, sun)["dni"]


def clear_sky_irradiance(times, site: Site, sun: pd.DataFrame | None = None) -> pd.DataFrame:
    """Clear-sky direct normal and diffuse horizontal irradiance at the site (Ineichen & Perez 2002, as
    implemented by pvlib).

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
    pandas.DataFrame  [W/m^2]
        ``dni`` and ``dhi``, indexed by ``times``; 0 while the sun is down. Kept by content
        (:mod:`heliostep.solar.sun_cache`): the same grid again is read back, pvlib not imported.
    """
    times = check_times(times)

    def compute() -> pd.DataFrame:
        import pvlib

        location = pvlib.location.Location(site.latitude, site.longitude, site.timezone, site.altitude)
        with warnings.catch_warnings():  # pvlib's pandas deprecations are not ours to fix
            warnings.simplefilter("ignore")
            sky = location.get_clearsky(times, model="ineichen", solar_position=sun)  # Ineichen & Perez (2002)
        return sky[["dni", "dhi"]].fillna(0.0).clip(lower=0.0)

    # kept by content (heliostep.solar.sun_cache): every input of the model, the given sun's columns it reads too
    given = () if sun is None else tuple(sun[column].to_numpy(dtype=float) for column in _SUN_COLUMNS_READ)
    parameters = ("ineichen", site.latitude, site.longitude, site.timezone, site.altitude, sun is None, *given)
    return cached_frame("clear_sky", times, parameters, compute)


def _check_site(path: Path, meta, site: Site, max_offset: float) -> None:
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


def _wind(data: pd.DataFrame, epw: bool) -> tuple[np.ndarray, np.ndarray]:
    """The file's wind speed [m/s] and direction [deg from north, clockwise], NaN where missing
    (or, for the direction, undefined: EPW's 0 means calm/undefined, its north is 360)."""
    n = len(data)
    speed = (
        pd.to_numeric(data["wind_speed"], errors="coerce").to_numpy(float)
        if "wind_speed" in data
        else np.full(n, np.nan)
    )
    speed = np.where((speed >= 0.0) & (speed < MAX_WIND_SPEED), speed, np.nan)
    if "wind_direction" not in data:
        return speed, np.full(n, np.nan)
    direction = pd.to_numeric(data["wind_direction"], errors="coerce").to_numpy(float)
    low = 0.0 if epw else -1e-9  # EPW: 0 is "undefined, calm" (pvlib's read_epw docs); TMY3: 0 is north
    return speed, np.where((direction > low) & (direction <= 360.0), direction, np.nan)


def _air_temperature(data: pd.DataFrame) -> np.ndarray:
    """The file's dry-bulb temperature [degC], NaN where missing (EPW 99.9, TMY3 -9900: outside
    [-90, 70) degC)."""
    if "temp_air" not in data:
        return np.full(len(data), np.nan)
    temperature = pd.to_numeric(data["temp_air"], errors="coerce").to_numpy(float)
    return np.where((temperature >= -90.0) & (temperature < 70.0), temperature, np.nan)


def read_weather(path, site: Site, max_offset: float = MAX_SITE_OFFSET) -> pd.DataFrame:
    """Hourly DNI and wind of a TMY3 (``.csv``) or EPW (``.epw``) file for the site, indexed by
    the end of each record's hour (the module's docstring: the files' time convention).

    Parameters
    ----------
    path : str or pathlib.Path
    site : Site
        The file's header latitude and longitude must be within ``max_offset`` of it.
    max_offset : float, default MAX_SITE_OFFSET  [deg]

    Returns
    -------
    pandas.DataFrame
        Indexed by the record's end (the file's stamp, in its standard time): ``dni`` and ``dhi`` (diffuse
        horizontal; NaN where the file has none) [W/m^2], the means over the hour ending then;
        ``wind_speed`` [m/s] and ``wind_direction`` [deg from north, clockwise], measured then (NaN
        where the file has none or marks them missing);
        ``temp_air`` [degC], the dry-bulb temperature then (NaN likewise).

    Raises
    ------
    InputError
        Naming the file and the key (``weather_file``, ``latitude``, ``longitude``, ``dni``).
    """
    import pvlib

    max_offset = check_positive(max_offset, "max_offset", "deg")
    path = Path(path)
    epw = path.suffix.lower() == ".epw"
    try:
        check_input_file(path, "weather", MAX_WEATHER_BYTES)
    except InputError as exc:
        raise InputError(f"weather_file {exc}") from None
    try:
        data, meta = (
            pvlib.iotools.read_epw(str(path)) if epw else pvlib.iotools.read_tmy3(str(path), map_variables=True)
        )
    except Exception as exc:
        raise InputError(f"weather_file {path}: cannot read it as {path.suffix or 'TMY3'} ({exc})") from exc
    _check_site(path, meta, site, max_offset)
    column = "dni" if "dni" in data else "DNI" if "DNI" in data else None
    if column is None:
        raise InputError(f"weather_file {path}: no dni column")
    dni = pd.to_numeric(data[column], errors="coerce")
    if dni.isna().any() or (dni < 0).any():
        raise InputError(f"weather_file {path}: dni has missing or negative values")
    # pvlib indexes an EPW record of hour h at h - 1 (its start), a TMY3 record at its stamp (its end)
    end = data.index + RECORD if epw else data.index
    speed, direction = _wind(data, epw)
    diffuse = next((data[c] for c in ("dhi", "DHI") if c in data), pd.Series(np.nan, index=data.index))
    diffuse = pd.to_numeric(diffuse, errors="coerce").where(lambda v: v >= 0)  # missing or negative: NaN
    frame = {
        "dni": dni.to_numpy(float),
        "dhi": diffuse.to_numpy(float),
        "wind_speed": speed,
        "wind_direction": direction,
    }
    return pd.DataFrame({**frame, "temp_air": _air_temperature(data)}, index=end)


def _hour_key(stamps: pd.DatetimeIndex) -> np.ndarray:
    """A typical year's key of whole-hour stamps: (month * 100 + day) * 100 + hour (the year ignored)."""
    return np.asarray((stamps.month * 100 + stamps.day) * 100 + stamps.hour)


@dataclass(frozen=True)
class WeatherSeries:
    """DNI and wind at the same instants, on a UTC index.

    ``dni`` [W/m^2]; ``wind_speed`` [m/s] and ``wind_direction`` [deg, the direction the wind
    blows from, clockwise from north], None when the source has no wind (clear sky), NaN where the
    file marks them missing.
    """

    dni: pd.Series
    wind_speed: pd.Series | None = None
    wind_direction: pd.Series | None = None
    air_temperature: pd.Series | None = None  # [degC], the file's dry bulb at its stamps, linear between

    @property
    def index(self) -> pd.DatetimeIndex:
        """The instants (UTC)."""
        return pd.DatetimeIndex(self.dni.index)


@dataclass(frozen=True)
class WeatherFile:
    """A typical-year weather file read once (:meth:`read`) and evaluated at any times of the
    year: DNI (:meth:`at`) and DNI with the wind (:meth:`series`), matched by month, day and hour
    of the file's standard time. The hours' mean DNI is placed at the middle of each hour and the
    instantaneous wind at the stamps, each interpolated linearly (the module's docstring: why)."""

    path: Path
    table: pd.Series  # mean DNI [W/m^2] of the hour starting at the key, placed at key + 30 min
    timezone: object  # the file's timezone (None: naive local time)
    wind: pd.DataFrame | None = None  # wind_speed [m/s], its components wind_u, wind_v [m/s] at the key
    diffuse: pd.Series | None = None  # mean diffuse horizontal irradiance [W/m^2], keyed as ``table``

    @classmethod
    def read(cls, path, site: Site, max_offset: float = MAX_SITE_OFFSET) -> WeatherFile:
        """The file's DNI and wind (:func:`read_weather`: raises InputError naming file and key)."""
        hourly = read_weather(path, site, max_offset)
        end = pd.DatetimeIndex(hourly.index)
        # the hour's mean at its middle, end - 30 min: keyed by the hour it starts, end - 1 h
        table = pd.Series(hourly["dni"].to_numpy(), index=_hour_key(end - RECORD)).groupby(level=0).mean()
        diffuse = pd.Series(hourly["dhi"].to_numpy(), index=_hour_key(end - RECORD)).groupby(level=0).mean()
        rad = np.radians(hourly["wind_direction"].to_numpy())
        speed = hourly["wind_speed"].to_numpy()
        wind = pd.DataFrame(
            {
                "wind_speed": speed,
                "wind_u": speed * np.sin(rad),
                "wind_v": speed * np.cos(rad),
                "temp_air": hourly["temp_air"].to_numpy(),
            },
            index=_hour_key(end),
        )
        return cls(Path(path), table.rename("dni"), end.tz, wind.groupby(level=0).mean(), diffuse.rename("dhi"))

    def _interpolate(self, times, table: pd.DataFrame, shift: pd.Timedelta, name: str) -> dict[str, np.ndarray]:
        """``table``'s columns at ``times``, linear between its points, at key + ``shift``."""
        times = check_times(times)
        local = times.tz_convert(self.timezone) if self.timezone is not None else times.tz_localize(None)
        local = local - shift
        floor = local.floor("h")
        fraction = ((local - floor) / RECORD).to_numpy()
        keys = [_hour_key(floor), _hour_key(floor + RECORD)]
        if not np.isin(keys[0], table.index).all() or not np.isin(keys[1][fraction > 0], table.index).all():
            raise InputError(
                f"weather_file {self.path}: does not cover the window {times[0]} - {times[-1]} (key: window; {name})"
            )
        out = {}
        for column in table.columns:
            low, high = (table[column].reindex(key).to_numpy() for key in keys)
            out[column] = low + fraction * (np.where(fraction > 0, high, low) - low)
        return out

    def at(self, times) -> pd.Series:
        """DNI [W/m^2] at ``times`` (timezone-aware), named ``dni``: each hour's mean at the
        middle of its hour, interpolated linearly; InputError (key ``window``) when the file does
        not cover them."""
        values = self._interpolate(times, self.table.to_frame(), MID_RECORD, "dni")["dni"]
        return pd.Series(values, index=check_times(times), name="dni")

    def diffuse_at(self, times) -> pd.Series:
        """Diffuse horizontal irradiance [W/m^2] at ``times``, as :meth:`at` places and interpolates DNI;
        InputError (key ``dhi``) when the file gives none there."""
        if self.diffuse is None:
            raise InputError(f"weather_file {self.path}: no dhi column")
        values = self._interpolate(times, self.diffuse.to_frame(), MID_RECORD, "dhi")["dhi"]
        if np.isnan(values).any():
            raise InputError(f"weather_file {self.path}: dhi missing within the window (key: dhi)")
        return pd.Series(values, index=check_times(times), name="dhi")

    def series(self, times) -> WeatherSeries:
        """DNI (:meth:`at`) and the wind at ``times``, on their UTC index; InputError (key
        ``window``) when the file does not cover them."""
        times = check_times(times)
        utc = times.tz_convert("UTC")
        if self.wind is None:
            return WeatherSeries(dni=pd.Series(self.at(times).to_numpy(), index=utc, name="dni"))
        wind = self._interpolate(times, self.wind, pd.Timedelta(0), "wind")
        direction = np.degrees(np.arctan2(wind["wind_u"], wind["wind_v"])) % 360.0
        direction = np.where(np.hypot(wind["wind_u"], wind["wind_v"]) > 0.0, direction, np.nan)
        return WeatherSeries(
            dni=pd.Series(self.at(times).to_numpy(), index=utc, name="dni"),
            wind_speed=pd.Series(wind["wind_speed"], index=utc, name="wind_speed"),
            wind_direction=pd.Series(direction, index=utc, name="wind_direction"),
            air_temperature=pd.Series(wind["temp_air"], index=utc, name="temp_air"),
        )


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
        Named ``dni``, indexed by ``times`` (:meth:`WeatherFile.at` of the file read once).
    """
    return WeatherFile.read(path, site, max_offset).at(times)


def dni(times, site: Site, weather_file=None, sun: pd.DataFrame | None = None) -> pd.Series:
    """DNI over a window: clear sky unless a weather file (a path, or a :class:`WeatherFile`
    already read) is given; ``sun``: see :func:`clear_sky_dni`.

    Returns
    -------
    pandas.Series  [W/m^2]
    """
    if weather_file is None:
        return clear_sky_dni(times, site, sun)
    if isinstance(weather_file, WeatherFile):
        return weather_file.at(times)
    return weather_dni(times, site, weather_file)


def weather_series(times, site: Site, weather_file=None, sun: pd.DataFrame | None = None) -> WeatherSeries:
    """DNI and wind over a window (UTC index): a weather file's (a path or a :class:`WeatherFile`),
    or the clear sky's DNI with no wind (``wind_speed`` and ``wind_direction`` None)."""
    if weather_file is None:
        times = check_times(times)
        return WeatherSeries(dni=clear_sky_dni(times, site, sun).set_axis(times.tz_convert("UTC")))
    weather = weather_file if isinstance(weather_file, WeatherFile) else WeatherFile.read(weather_file, site)
    return weather.series(times)


def cloud_fraction(seconds, clouds) -> np.ndarray:
    """The share of the direct irradiance left at ``seconds`` [s from the window's start] under ``clouds``,
    (start [s], end [s], fraction [-]) each: the fraction within [start, end), 1 elsewhere."""
    seconds = np.asarray(seconds, dtype=float)
    left = np.ones_like(seconds)
    for start, end, fraction in clouds:
        left[(seconds >= start) & (seconds < end)] *= fraction
    return left
