"""Light on the tube of every end mirror of the field, per day over a year, with the shared primary.

What the co-simulated field sweep (:func:`heliostep.sweep.run_field`) gives per case, without
co-simulating: the secondary's stepping changes the light by +-2e-7 of it, a first-order cosine
term of either sign and not a loss (:mod:`heliostep.results.light`), so over a year the loss per
mirror is the shared primary's (exactly 0 for the central mirror, whose primary is the shared
one). For each day and mirror i of the field (:func:`heliostep.solar.field_distances`):

- **ideal**: both axes follow the mirror's own two-axis law ([paper], eqs. 3-6);
- **shared primary**: the primary follows the central mirror's law plus the mounting offset
  that makes it exact at that day's solar noon (:func:`heliostep.solar.sharing_errors`), the
  secondary its own law (exact, as its own stepper keeps it within 0.006 deg);

and the power on the tube of each attitude by :func:`heliostep.results.light.attitude_light`
(cosine, Gaussian beam spread, intercept on the tube), integrated over the day (trapezoid on
a ``step_minutes`` grid from local midnight). DNI: the scenario's (clear sky, or its weather file,
read once: :class:`heliostep.solar.irradiance.WeatherFile`, its hourly means at mid-hour).
"""

from __future__ import annotations

import datetime as dt

import numpy as np
import pandas as pd

from heliostep.errors import InputError
from heliostep.results.light import attitude_light, read_weather_file
from heliostep.solar import DEFAULT_MIRROR_SPACING, N_FIELD_MIRRORS, field_distances, irradiance, sharing_errors
from heliostep.solar.sun import solar_position, sun_vector
from heliostep.solar.tracking import two_axis_angles


def field_light_days(scenario, days=None, step_minutes: float = 10.0, mirror_indices=None) -> pd.DataFrame:
    """Energy on the tube per day and mirror, ideal two-axis tracking vs the shared primary.

    Parameters
    ----------
    scenario : heliostep.scenario.Scenario
        Its site, plant, optics and ``mirror.spacing``; the year of ``window.date``.
    days : iterable of int, optional
        Days of that year (default every day).
    step_minutes : float, default 10  [min]
    mirror_indices : iterable of int, optional
        Mirrors 0 .. 12 (default all; 6 is the central one).

    Returns
    -------
    pandas.DataFrame
        One row per (day, mirror): ``day_of_year``, ``date``, ``mirror_index``,
        ``mirror_distance_m``, ``light_energy_ideal_J``, ``light_energy_J`` (shared primary),
        ``light_lost_shared_primary_J`` = ``light_lost_J`` [J], ``light_lost_fraction`` [-] and
        ``status`` "ok" (the columns of the sweep table, for :func:`heliostep.plots.sweep.plot_heatmap`).
    """
    year = scenario.window.date.year
    n_days = (dt.date(year + 1, 1, 1) - dt.date(year, 1, 1)).days
    chosen = list(range(1, n_days + 1)) if days is None else [int(d) for d in days]
    if not chosen or min(chosen) < 1 or max(chosen) > n_days:
        raise InputError(f"days: expected days of year 1 .. {n_days}, got {days!r}")
    indices = list(range(N_FIELD_MIRRORS)) if mirror_indices is None else [int(i) for i in mirror_indices]
    if not indices or min(indices) < 0 or max(indices) >= N_FIELD_MIRRORS:
        raise InputError(f"mirror indices: expected 0 .. {N_FIELD_MIRRORS - 1}, got {mirror_indices!r}")
    if not step_minutes > 0:
        raise InputError(f"step_minutes {step_minutes!r}: expected > 0 [min]")
    distances = field_distances(N_FIELD_MIRRORS, scenario.mirror.spacing or DEFAULT_MIRROR_SPACING)[indices]
    weather = read_weather_file(scenario)  # the whole year: no window to check
    rows = []
    for day in chosen:
        date = dt.date(year, 1, 1) + dt.timedelta(days=day - 1)
        rows += _day_rows(scenario, date, day, step_minutes, indices, distances, weather)
    return pd.DataFrame(rows)


def _day_rows(
    scenario, date: dt.date, day: int, step_minutes: float, indices: list[int], distances, weather=None
) -> list[dict]:
    """The table's rows of one day (see :func:`field_light_days`), one per mirror; ``weather``:
    the scenario's weather file already read (None: clear sky)."""
    site, plant, conf = scenario.site.to_site(), scenario.plant.to_plant(), scenario.optics
    start = pd.Timestamp(date).tz_localize(site.timezone)
    stop = pd.Timestamp(date + dt.timedelta(days=1)).tz_localize(site.timezone)
    times = pd.date_range(start, stop, freq=pd.Timedelta(minutes=step_minutes))
    position = solar_position(times, site.latitude, site.longitude, site.altitude)
    elevation, azimuth = position["apparent_elevation"].to_numpy(), position["azimuth"].to_numpy()
    up = elevation > 0.0
    sun = np.stack(sun_vector(elevation, azimuth, plant.azimuth))
    dni = irradiance.dni(times, site, weather).to_numpy()
    seconds = (times - start).total_seconds().to_numpy()
    sharing = np.nan_to_num(sharing_errors(times, site, plant, date, distances))
    sharing[:, np.asarray(distances) == 0.0] = 0.0  # the central mirror's primary is the shared one
    rows = []
    for k, (index, distance) in enumerate(zip(indices, distances)):
        primary, secondary = two_axis_angles(elevation, azimuth, distance, plant.tube_height, plant.azimuth)
        ideal = attitude_light(sun, dni, up, primary, secondary, distance, plant.tube_height, conf)["power_W"]
        shared = attitude_light(sun, dni, up, primary - sharing[:, k], secondary, distance, plant.tube_height, conf)[
            "power_W"
        ]
        e_ideal, e_shared = float(np.trapezoid(ideal, seconds)), float(np.trapezoid(shared, seconds))
        rows.append(
            {
                "day_of_year": day,
                "date": date.isoformat(),
                "mirror_index": index,
                "mirror_distance_m": float(distance),
                "light_energy_ideal_J": e_ideal,
                "light_energy_J": e_shared,
                "light_lost_shared_primary_J": e_ideal - e_shared,
                "light_lost_J": e_ideal - e_shared,
                "light_lost_fraction": (e_ideal - e_shared) / e_ideal if e_ideal > 0 else 0.0,
                "status": "ok",
            }
        )
    return rows
