"""Tests of heliostep.solar.irradiance: clear-sky DNI and typical-year weather files."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from heliostep.errors import InputError
from heliostep.solar import irradiance
from heliostep.solar.sun import Site
from weather_files import write_epw

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


def test_epw_file_is_read_and_interpolated(tmp_path):
    path = _write_epw(tmp_path / "site.epw")
    times = pd.date_range("2026-01-21 10:00", "2026-01-21 11:00", freq="15min", tz="Etc/GMT-1")
    dni = irradiance.dni(times, SITE, weather_file=path)
    hourly = irradiance.read_weather(path, SITE)
    at_ten = hourly[(hourly.index.hour == 10)].iloc[0]
    at_eleven = hourly[(hourly.index.hour == 11)].iloc[0]
    np.testing.assert_allclose(dni.to_numpy(), at_ten + np.linspace(0, 1, 5) * (at_eleven - at_ten))


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
