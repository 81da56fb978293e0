"""Tiny TMY3 and EPW weather files the tests write themselves (no download): hourly rows of one day.

Both formats stamp a record with the END of its hour: its irradiance is the mean over the hour
ending then, its wind measured then (TMY3: Wilcox & Marion, NREL/TP-581-43156, 2008; EPW: the
EnergyPlus Auxiliary Programs manual, hours 1 .. 24). ``dni_of_hour(h)`` is the mean DNI of the
hour ending at h, ``wind_of_hour(h)`` and ``direction_of_hour(h)`` the wind at h.
"""

from __future__ import annotations


def write_epw(
    path,
    latitude=40.0,
    longitude=-3.7,
    dni_of_hour=lambda h: 50.0 * h,
    month=1,
    day=21,
    wind_of_hour=lambda h: 0.0,
    direction_of_hour=lambda h: 0.0,
    timezone_hours=1.0,
):
    """An EPW file with the LOCATION header and 24 hourly rows of one day; DNI per hour 1..24 [W/m^2]."""
    header = [
        f"LOCATION,Test,NA,ESP,test,000000,{latitude},{longitude},{timezone_hours},600.0",
        "DESIGN CONDITIONS,0",
        "TYPICAL/EXTREME PERIODS,0",
        "GROUND TEMPERATURES,0",
        "HOLIDAYS/DAYLIGHT SAVINGS,No,0,0,0",
        "COMMENTS 1,test",
        "COMMENTS 2,test",
        f"DATA PERIODS,1,1,Data,Sunday, {month}/{day},{month}/{day}",
    ]
    rows = []
    for hour in range(1, 25):  # EPW hours 1..24 label the hour ending then
        values = [1999, month, day, hour, 0, "?", 10.0, 5.0, 60, 95000, 0, 0, 300, 0, dni_of_hour(hour), 0]
        values += [0, 0, 0, 0, direction_of_hour(hour), wind_of_hour(hour)]  # fields 17-22: illuminances, wind
        values += [0] * (35 - len(values))
        rows.append(",".join(str(v) for v in values))
    path.write_text("\n".join(header + rows) + "\n")
    return path


def write_tmy3(
    path,
    latitude=40.0,
    longitude=-3.7,
    dni_of_hour=lambda h: 50.0 * h,
    month=1,
    day=21,
    year=1999,
    wind_of_hour=lambda h: 0.0,
    direction_of_hour=lambda h: 0.0,
    timezone_hours=1.0,
):
    """A TMY3 file (header line, column line, 24 hourly rows 01:00 .. 24:00 of one day) with the
    columns heliostep reads: date, time, DNI [W/m^2], wind direction [deg] and speed [m/s]."""
    lines = [
        f"000000,'TEST',XX,{timezone_hours},{latitude},{longitude},600",
        "Date (MM/DD/YYYY),Time (HH:MM),GHI (W/m^2),DNI (W/m^2),DHI (W/m^2),Wdir (degrees),Wspd (m/s)",
    ]
    for hour in range(1, 25):
        lines.append(
            f"{month:02d}/{day:02d}/{year},{hour:02d}:00,0,{dni_of_hour(hour)},0,{direction_of_hour(hour)},"
            f"{wind_of_hour(hour)}"
        )
    path.write_text("\n".join(lines) + "\n")
    return path
