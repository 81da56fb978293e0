"""Tiny EPW weather files the tests write themselves (no download): one day of hourly rows."""

from __future__ import annotations


def write_epw(path, latitude=40.0, longitude=-3.7, dni_of_hour=lambda h: 50.0 * h, month=1, day=21):
    """An EPW file with the LOCATION header and 24 hourly rows of one day; DNI per hour 1..24 [W/m^2]."""
    header = [
        f"LOCATION,Test,NA,ESP,test,000000,{latitude},{longitude},1.0,600.0",
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
        values += [0] * (35 - len(values))
        rows.append(",".join(str(v) for v in values))
    path.write_text("\n".join(header + rows) + "\n")
    return path
