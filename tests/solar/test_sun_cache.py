"""Tests of heliostep.solar.sun_cache: pvlib's sun grids kept by content give pvlib's own values bit for
bit, and any changed input is another entry (pvlib computes it again).

Every expected value is pvlib's, called directly here (``pvlib.solarposition.get_solarposition``,
``Location.get_clearsky``, ``sun_rise_set_transit_spa``), never the cache's first answer re-read.
"""

from __future__ import annotations

import datetime as dt
import os
import warnings

import numpy as np
import pandas as pd
import pvlib
import pytest

from heliostep.solar import irradiance, sun_cache
from heliostep.solar.sun import Site, solar_position, sun_events

SITE = Site(latitude=40.0, longitude=14.25, altitude=120.0, timezone="Europe/Rome")
TIMES = pd.date_range("2025-01-21 10:00", periods=301, freq="1s", tz=SITE.timezone, unit="ns")


@pytest.fixture
def cache(tmp_path, monkeypatch):
    """A cache folder of the test's own (the FMU cache's ``sun-grids``); the entries written there."""
    monkeypatch.setenv("HELIOSTEP_FMUS", str(tmp_path))
    return tmp_path / "sun-grids"


def pvlib_position(times, latitude, longitude, altitude) -> pd.DataFrame:
    return pvlib.solarposition.get_solarposition(times, latitude, longitude, altitude=altitude, method="nrel_numpy")


def assert_bits_equal(found: pd.DataFrame, expected: pd.DataFrame) -> None:
    """Same index, columns in the same order, every value's float64 bits the same."""
    assert list(found.columns) == list(expected.columns)
    assert found.index.equals(expected.index)
    for column in expected.columns:
        assert found[column].dtype == expected[column].dtype == np.float64
        assert np.array_equal(found[column].to_numpy().view(np.int64), expected[column].to_numpy().view(np.int64))


def entries(folder) -> set[str]:
    return {path.name for path in folder.glob("*.npz")} if folder.exists() else set()


def test_a_sun_position_read_back_is_pvlibs_bit_for_bit_and_each_changed_input_is_a_new_entry(cache):
    expected = pvlib_position(TIMES, SITE.latitude, SITE.longitude, SITE.altitude)
    first = solar_position(TIMES, SITE.latitude, SITE.longitude, SITE.altitude)
    assert len(entries(cache)) == 1
    again = solar_position(TIMES, SITE.latitude, SITE.longitude, SITE.altitude)
    assert len(entries(cache)) == 1  # read back, not computed and written again
    assert_bits_equal(first, expected)
    assert_bits_equal(again, expected)

    # each input changed (the latitude in its last bit, one instant by a nanosecond, the altitude): a new
    # entry, and pvlib's value at the new input, which differs from the old one (a nanosecond moves none)
    latitude = np.nextafter(SITE.latitude, 90.0)
    shifted = TIMES.delete(150).insert(150, TIMES[150] + pd.Timedelta(1, "ns"))
    changed = {
        "latitude": ((TIMES, latitude, SITE.longitude, SITE.altitude), "zenith"),
        "one instant": ((shifted, SITE.latitude, SITE.longitude, SITE.altitude), None),  # (SPA's values alike)
        "altitude": ((TIMES, SITE.latitude, SITE.longitude, 121.0), "apparent_zenith"),
    }
    for count, (name, (arguments, column)) in enumerate(changed.items(), start=2):
        found = solar_position(*arguments)
        assert len(entries(cache)) == count, name
        assert_bits_equal(found, pvlib_position(*arguments))
        if column is not None:
            assert not np.array_equal(found[column].to_numpy(), expected[column].to_numpy()), name


def test_a_damaged_entry_is_computed_again(cache):
    expected = pvlib_position(TIMES, SITE.latitude, SITE.longitude, SITE.altitude)
    solar_position(TIMES, SITE.latitude, SITE.longitude, SITE.altitude)
    (entry,) = cache.glob("*.npz")
    entry.write_bytes(entry.read_bytes()[:100])  # cut short (a disk that failed, a foreign file)
    assert_bits_equal(solar_position(TIMES, SITE.latitude, SITE.longitude, SITE.altitude), expected)
    assert entry.stat().st_size > 100  # written again whole


def test_the_clear_sky_and_the_sun_events_read_back_are_pvlibs(cache):
    sun = solar_position(TIMES, SITE.latitude, SITE.longitude, SITE.altitude)
    location = pvlib.location.Location(SITE.latitude, SITE.longitude, SITE.timezone, SITE.altitude)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sky = location.get_clearsky(TIMES, model="ineichen", solar_position=sun)["dni"]
    expected = sky.fillna(0.0).clip(lower=0.0)
    assert expected.max() > 500.0  # a January morning's clear sky at 40 deg N: the sun is up
    for _ in range(2):  # computed, then read back
        dni = irradiance.clear_sky_dni(TIMES, SITE, sun)
        assert dni.name == "dni" and dni.index.equals(TIMES)
        assert np.array_equal(dni.to_numpy().view(np.int64), expected.to_numpy().view(np.int64))
    # another sun given (its apparent zenith moved in one row): another entry
    moved = sun.copy()
    moved.iloc[10, moved.columns.get_loc("apparent_zenith")] += 1.0
    before = len(entries(cache))
    irradiance.clear_sky_dni(TIMES, SITE, moved)
    assert len(entries(cache)) == before + 1

    date = dt.date(2025, 1, 21)
    noon = pd.DatetimeIndex([pd.Timestamp("2025-01-21 12:00")]).tz_localize(SITE.timezone)
    spa = pvlib.solarposition.sun_rise_set_transit_spa(noon, SITE.latitude, SITE.longitude)
    for _ in range(2):
        events = sun_events(date, SITE)
        for column in ("sunrise", "transit", "sunset"):
            assert events[column] == spa[column].iloc[0] and str(events[column].tz) == SITE.timezone
    polar = Site(latitude=89.0, longitude=0.0, timezone="UTC")
    for _ in range(2):  # polar night: no sunrise, no sunset, read back as None
        events = sun_events(dt.date(2025, 12, 21), polar)
        assert events["sunrise"] is None and events["sunset"] is None and events["transit"] is not None


def test_the_least_recently_used_entries_go_beyond_the_limit(cache, monkeypatch):
    monkeypatch.setattr(sun_cache, "MAX_ENTRIES", 2)
    grids = [TIMES[:10] + pd.Timedelta(k, "min") for k in range(3)]
    names = []
    for age, grid in enumerate(grids[:2]):
        solar_position(grid, SITE.latitude, SITE.longitude)
        (new,) = entries(cache) - set(names)
        names.append(new)
        os.utime(cache / new, (1000.0 + age, 1000.0 + age))  # the first written is the older
    solar_position(grids[0], SITE.latitude, SITE.longitude)  # read back: now the more recently used
    assert entries(cache) == set(names)
    solar_position(grids[2], SITE.latitude, SITE.longitude)
    kept = entries(cache)
    assert len(kept) == 2 and names[0] in kept and names[1] not in kept
