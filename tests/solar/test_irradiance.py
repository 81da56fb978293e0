"""Tests of heliostep.solar.irradiance: clear-sky DNI and typical-year weather files (their time
convention and their wind), on TMY3 and EPW files written by the test."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from heliostep.errors import InputError
from heliostep.solar import irradiance
from heliostep.solar.sun import Site
from weather_files import write_epw, write_tmy3

SITE = Site(latitude=40.0, longitude=-3.7, altitude=600.0, timezone="Etc/GMT-1")
#: Order of magnitude of clear-sky DNI at noon, mid-latitudes: the solar constant 1361 W/m^2
#: attenuated by a clean atmosphere to roughly 700-1000 W/m^2 (Duffie & Beckman, 4th ed., 2.8).
SOLAR_CONSTANT = 1361.0  # [W/m^2]


_write_epw = write_epw


def test_clear_sky_dni_is_physical():
    times = pd.date_range("2026-01-21 06:00", "2026-01-21 18:00", freq="10min", tz=SITE.timezone)
    dni = irradiance.clear_sky_dni(times, SITE)
    assert dni.name == "dni" and dni.index.equals(times)
    assert (dni >= 0).all() and dni.max() < SOLAR_CONSTANT
    assert 600.0 < dni.max() < 1100.0
    assert dni.iloc[0] == 0.0  # before sunrise (~08:30 local)
    assert dni.idxmax().hour in (11, 12, 13)


def test_epw_file_is_read_and_interpolated_between_the_middles_of_its_hours(tmp_path):
    # the EPW row of hour h holds the mean over (h - 1, h]: hour 11's (550) at 10:30, hour 12's (600) at 11:30
    path = _write_epw(tmp_path / "site.epw")
    times = pd.date_range("2026-01-21 10:30", "2026-01-21 11:30", freq="15min", tz="Etc/GMT-1")
    dni = irradiance.dni(times, SITE, weather_file=path)
    np.testing.assert_allclose(dni.to_numpy(), 550.0 + np.linspace(0, 1, 5) * 50.0)


#: A day's DNI linear within each hour [W/m^2]: 0 until 07:00, up to 900 at 13:00, down to 0 at
#: 17:00 (local standard time). Its energy and centroid in closed form (a triangle):
TRIANGLE = (7.0, 13.0, 17.0, 900.0)  # start, peak, end [h], peak [W/m^2]
TRIANGLE_ENERGY = 0.5 * 900.0 * (17.0 - 7.0) * 3600.0  # [J/m^2]
TRIANGLE_CENTROID_H = (7.0 + 13.0 + 17.0) / 3.0  # [h]: 12:20


def _triangle(t):
    start, peak, end, top = TRIANGLE
    return np.interp(t, [start, peak, end], [0.0, top, 0.0])


def _hour_mean(hour):
    """The mean of the triangle over the hour ending at ``hour``: the value at its middle (linear within it)."""
    return float(_triangle(hour - 0.5))


def _day_moments(dni: pd.Series, day_start: pd.Timestamp) -> tuple[float, float]:
    """The energy [J/m^2] and the centroid [h after day_start] of a DNI series (trapezoid)."""
    hours = ((dni.index - day_start) / pd.Timedelta(hours=1)).to_numpy()
    values = dni.to_numpy()
    energy = np.trapezoid(values, hours * 3600.0)
    return float(energy), float(np.trapezoid(values * hours, hours * 3600.0) / energy)


@pytest.mark.parametrize("write", [write_tmy3, write_epw], ids=["tmy3", "epw"])
def test_the_days_light_keeps_its_energy_and_its_time(tmp_path, write):
    """The file's hourly means of a triangle of DNI give back the triangle's energy and centroid.

    Linear interpolation between the hours' middles is a sum of hat functions of area mean x 1 h
    centred on the middles, and for light linear within each hour the middles' moment is the
    true one: both agree to the quadrature of a 1-minute grid (exact for a piecewise-linear
    function sampled at its kinks, the :30 points). Tolerances: 1e-9 of the energy, 1 s of time.
    Interpolating the means at the stamps instead puts the centroid 30 min late (TMY3) or, at
    pvlib's EPW stamps (the hour's start), 30 min early."""
    path = write(tmp_path / f"triangle.{'csv' if write is write_tmy3 else 'epw'}", dni_of_hour=_hour_mean)
    day_start = pd.Timestamp("2026-01-21 00:00", tz="Etc/GMT-1")
    times = day_start + pd.to_timedelta(np.arange(120, 23 * 60 + 1), unit="min")  # 02:00 .. 23:00
    energy, centroid = _day_moments(irradiance.dni(times, SITE, weather_file=path), day_start)
    assert energy == pytest.approx(TRIANGLE_ENERGY, rel=1e-9)
    assert abs(centroid - TRIANGLE_CENTROID_H) * 3600.0 < 1.0
    # the test's power: the same means interpolated at pvlib's stamps miss the centroid by 30 min
    raw, _ = (pvlib_read_epw if write is write_epw else pvlib_read_tmy3)(path)
    stamps_h = ((raw.index - raw.index[0].normalize()) / pd.Timedelta(hours=1)).to_numpy()  # the file's year
    naive = pd.Series(np.interp((times - day_start) / pd.Timedelta(hours=1), stamps_h, raw["dni"]), index=times)
    _, naive_centroid = _day_moments(naive, day_start)
    assert abs(abs(naive_centroid - TRIANGLE_CENTROID_H) - 0.5) * 3600.0 < 1.0


def pvlib_read_epw(path):
    import pvlib

    return pvlib.iotools.read_epw(str(path))


def pvlib_read_tmy3(path):
    import pvlib

    return pvlib.iotools.read_tmy3(str(path), map_variables=True)


def test_read_weather_stamps_every_record_with_the_end_of_its_hour(tmp_path):
    # the rule heliostep relies on: pvlib stamps a TMY3 record at its end (01:00 .. 24:00 -> 00:00
    # of the next day) and an EPW record of hour h at h - 1; read_weather puts both at the hour's end
    mean = lambda h: 10.0 * h  # noqa: E731
    for path in (write_tmy3(tmp_path / "a.csv", dni_of_hour=mean), write_epw(tmp_path / "a.epw", dni_of_hour=mean)):
        hourly = irradiance.read_weather(path, SITE)
        ends = hourly.index.hour.to_numpy()
        np.testing.assert_array_equal(ends, np.r_[1:24, 0])
        np.testing.assert_allclose(hourly["dni"].to_numpy(), 10.0 * np.arange(1, 25))
        assert hourly.index[-1] == pd.Timestamp("1999-01-22 00:00", tz="Etc/GMT-1")


@pytest.mark.parametrize("write", [write_tmy3, write_epw], ids=["tmy3", "epw"])
def test_wind_is_read_at_the_stamps_and_carried_with_the_dni(tmp_path, write):
    # the wind is measured at the stamp (both formats: "at the time indicated"): speed h m/s at h,
    # direction 350 deg until 10:00 and 10 deg from 11:00 (crossing north between them)
    path = write(
        tmp_path / f"wind.{'csv' if write is write_tmy3 else 'epw'}",
        wind_of_hour=lambda h: float(h),
        direction_of_hour=lambda h: 350.0 if h <= 10 else 10.0,
    )
    times = pd.DatetimeIndex(["2026-01-21 10:15", "2026-01-21 10:30", "2026-01-21 12:00"]).tz_localize("Etc/GMT-1")
    weather = irradiance.WeatherFile.read(path, SITE).series(times)
    assert isinstance(weather, irradiance.WeatherSeries)
    assert str(weather.index.tz) == "UTC" and weather.index.equals(times.tz_convert("UTC"))
    np.testing.assert_allclose(weather.wind_speed.to_numpy(), [10.25, 10.5, 12.0])
    # the direction through the wind's vector: speeds 10 and 11 m/s at 350 and 10 deg
    u = np.interp([0.25, 0.5], [0, 1], [10 * np.sin(np.radians(350)), 11 * np.sin(np.radians(10))])
    v = np.interp([0.25, 0.5], [0, 1], [10 * np.cos(np.radians(350)), 11 * np.cos(np.radians(10))])
    expected = np.degrees(np.arctan2(u, v)) % 360.0
    np.testing.assert_allclose(weather.wind_direction.to_numpy(), [*expected, 10.0], atol=1e-9)
    assert weather.wind_direction.iloc[1] < 1.0  # just east of north, not south
    np.testing.assert_allclose(weather.dni.to_numpy(), irradiance.dni(times, SITE, weather_file=path).to_numpy())


def test_missing_wind_is_nan_and_clear_sky_has_none(tmp_path):
    path = write_epw(tmp_path / "calm.epw", wind_of_hour=lambda h: 999.0, direction_of_hour=lambda h: 999.0)
    times = pd.date_range("2026-01-21 10:00", periods=3, freq="10min", tz="Etc/GMT-1")
    weather = irradiance.weather_series(times, SITE, path)
    assert weather.wind_speed.isna().all() and weather.wind_direction.isna().all()  # EPW's missing code
    clear = irradiance.weather_series(times, SITE)
    assert clear.wind_speed is None and clear.wind_direction is None
    np.testing.assert_allclose(clear.dni.to_numpy(), irradiance.clear_sky_dni(times, SITE).to_numpy())


def test_file_for_another_site_is_an_error(tmp_path):
    path = _write_epw(tmp_path / "far.epw", latitude=45.0)
    with pytest.raises(InputError, match=r"far\.epw.*latitude"):
        irradiance.read_weather(path, SITE)


def test_unreadable_file_is_an_error(tmp_path):
    path = tmp_path / "garbage.epw"
    path.write_text("not a weather file\n")
    with pytest.raises(InputError, match=r"weather_file .*garbage\.epw"):
        irradiance.read_weather(path, SITE)
    with pytest.raises(InputError, match="missing.epw"):
        irradiance.read_weather(tmp_path / "missing.epw", SITE)


def test_window_outside_the_file_is_an_error(tmp_path):
    path = _write_epw(tmp_path / "site.epw")
    times = pd.date_range("2026-06-21 10:00", "2026-06-21 11:00", freq="15min", tz="Etc/GMT-1")
    with pytest.raises(InputError, match="window"):
        irradiance.weather_dni(times, SITE, path)
