"""Tiny TMY3 and EPW weather files the tests write themselves (no download): hourly rows of one day.

Both formats stamp a record with the END of its hour: its irradiance is the mean over the hour
ending then, its wind measured then (TMY3: Wilcox & Marion, NREL/TP-581-43156, 2008; EPW: the
EnergyPlus Auxiliary Programs manual, hours 1 .. 24). ``dni_of_hour(h)`` is the mean DNI of the
hour ending at h, ``wind_of_hour(h)`` and ``direction_of_hour(h)`` the wind at h.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import dataclass


@dataclass
class WeatherDay:
    """The site and the day of a test's weather file, and its hourly values (functions of the hour 1..24)."""

    latitude: float = 40.0  # [deg]
    longitude: float = -3.7  # [deg]
    dni_of_hour: Callable[[int], float] = lambda h: 50.0 * h  # [W/m^2]
    month: int = 1
    day: int = 21
    wind_of_hour: Callable[[int], float] = lambda h: 0.0  # [m/s]
    direction_of_hour: Callable[[int], float] = lambda h: 0.0  # [deg]
    timezone_hours: float = 1.0  # [h] east of UTC
    dhi_of_hour: Callable[[int], float] = lambda h: 0.0  # [W/m^2]

    def hours(self) -> Iterator[tuple[int, float, float, float, float]]:
        """(hour 1..24, DNI, wind direction, wind speed, DHI) of each hour, the hour ending then."""
        for hour in range(1, 25):
            yield (
                hour,
                self.dni_of_hour(hour),
                self.direction_of_hour(hour),
                self.wind_of_hour(hour),
                self.dhi_of_hour(hour),
            )


def write_epw(path, **day):
    """An EPW file with the LOCATION header and 24 hourly rows of one day (``day``: :class:`WeatherDay`'s fields)."""
    d = WeatherDay(**day)
    header = [
        f"LOCATION,Test,NA,ESP,test,000000,{d.latitude},{d.longitude},{d.timezone_hours},600.0",
        "DESIGN CONDITIONS,0",
        "TYPICAL/EXTREME PERIODS,0",
        "GROUND TEMPERATURES,0",
        "HOLIDAYS/DAYLIGHT SAVINGS,No,0,0,0",
        "COMMENTS 1,test",
        "COMMENTS 2,test",
        f"DATA PERIODS,1,1,Data,Sunday, {d.month}/{d.day},{d.month}/{d.day}",
    ]
    rows = []
    for hour, dni, direction, wind, dhi in d.hours():  # EPW hours 1..24 label the hour ending then
        values = [1999, d.month, d.day, hour, 0, "?", 10.0, 5.0, 60, 95000, 0, 0, 300, 0, dni, dhi]
        values += [0, 0, 0, 0, direction, wind]  # fields 17-22: illuminances, wind
        values += [0] * (35 - len(values))
        rows.append(",".join(str(v) for v in values))
    path.write_text("\n".join(header + rows) + "\n")
    return path


def write_tmy3(path, year=1999, **day):
    """A TMY3 file (header line, column line, 24 hourly rows 01:00 .. 24:00 of one day of ``year``) with the
    columns heliostep reads: date, time, DNI and DHI [W/m^2], wind direction [deg] and speed [m/s]."""
    d = WeatherDay(**day)
    lines = [
        f"000000,'TEST',XX,{d.timezone_hours},{d.latitude},{d.longitude},600",
        "Date (MM/DD/YYYY),Time (HH:MM),GHI (W/m^2),DNI (W/m^2),DHI (W/m^2),Wdir (degrees),Wspd (m/s)",
    ]
    for hour, dni, direction, wind, dhi in d.hours():
        lines.append(f"{d.month:02d}/{d.day:02d}/{year},{hour:02d}:00,0,{dni},{dhi},{direction},{wind}")
    path.write_text("\n".join(lines) + "\n")
    return path
