"""Light on the tube of every end mirror of the field, per day over a year, with the shared primary.

Geometry and optics only, no co-simulation: the stepping changes the light by parts in 1e8, so over a
year a mirror's loss is the shared primary's; shading, blocking and the receiver's shadow included.

Details: docs/light.md, ``heliostep.results.light.field``.
"""

from __future__ import annotations

import datetime as dt
from collections.abc import Callable

import numpy as np
import pandas as pd

from heliostep.errors import InputError
from heliostep.results.light.mirror_power import attitude_light
from heliostep.results.light.on_tube import read_weather_file
from heliostep.solar import DEFAULT_MIRROR_SPACING, N_FIELD_MIRRORS, field_distances, irradiance, sharing_errors
from heliostep.solar.optics import mirror_normal
from heliostep.solar.receiver_shadow import receiver_shadow_fraction, receiver_width
from heliostep.solar.shading import interpolated_at_coarse_instants, row_losses
from heliostep.solar.sun import solar_position, sun_vector
from heliostep.solar.tracking import two_axis_angles


def field_light_days(
    scenario,
    days=None,
    step_minutes: float = 10.0,
    mirror_indices=None,
    shading: bool = True,
    shading_step_minutes: float = 30.0,
    progress: Callable[[int], object] | None = None,
) -> pd.DataFrame:
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
    shading : bool, default True
        Shading and blocking between the field's mirrors (every row, whichever are reported).
    shading_step_minutes : float, default 30  [min]
        Their time step, interpolated to ``step_minutes`` between.
    progress : callable, optional
        Called with 1 as each day is done.

    Returns
    -------
    pandas.DataFrame
        One row per (day, mirror): ``day_of_year``, ``date``, ``mirror_index``,
        ``mirror_distance_m``, ``light_energy_ideal_J``, ``light_energy_J`` (shared primary),
        ``light_lost_shared_primary_J`` = ``light_lost_J`` [J], ``light_lost_fraction`` [-],
        ``shading_lost_ideal_J`` (the light shading and blocking, the receiver's shadow included, take
        from ideal tracking) [J] and
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
    for name, value in (("step_minutes", step_minutes), ("shading_step_minutes", shading_step_minutes)):
        if not value > 0:
            raise InputError(f"{name} {value!r}: expected > 0 [min]")
    weather = read_weather_file(scenario)  # the whole year: no window to check
    every = max(1, round(shading_step_minutes / step_minutes)) if shading else None
    rows = []
    for day in chosen:
        date = dt.date(year, 1, 1) + dt.timedelta(days=day - 1)
        rows += _day_rows(scenario, date, day, step_minutes, indices, weather, every)
        if progress is not None:
            progress(1)
    return pd.DataFrame(rows)


def field_light_instants(
    scenario, times: pd.DatetimeIndex, date: dt.date, weather=None, shading_every: int | None = 1
) -> dict[str, np.ndarray]:
    """Power on the tube of each of the field's mirrors at each instant, ideal and with the shared primary.

    Parameters
    ----------
    scenario : heliostep.scenario.Scenario
    times : pandas.DatetimeIndex, tz-aware
        Instants (of one day, for the sharing's calibration).
    date : datetime.date
        The day whose solar noon makes the shared primary exact (:func:`heliostep.solar.sharing_errors`).
    weather : heliostep.solar.irradiance.WeatherFile, optional
        The scenario's weather file, already read (None: clear sky).
    shading_every : int or None, default 1
        Shading and blocking at every this-many instants with the sun up, interpolated between; None:
        the receiver's shadow only, no neighbours (see the module's docstring).

    Returns
    -------
    dict of numpy.ndarray, shape (T, N) but ``mirror_distance_m`` (N,)
        ``power_ideal_W``, ``power_shared_W`` [W] (unhidden), the same without shading and blocking
        ``power_ideal_unshaded_W``, ``power_shared_unshaded_W`` [W], ``unhidden_ideal``, ``unhidden_shared``
        (the share of each mirror neither shading nor blocking hides) [-], ``cosine_ideal``,
        ``cosine_shared`` [-], ``dni_W_m2`` (T,) and ``mirror_distance_m`` [m]; the N field mirrors in
        order (6 is the central one).
    """
    site, plant, conf = scenario.site.to_site(), scenario.plant.to_plant(), scenario.optics
    position = solar_position(times, site.latitude, site.longitude, site.altitude)
    elevation, azimuth = position["apparent_elevation"].to_numpy(), position["azimuth"].to_numpy()
    up = elevation > 0.0
    sun = np.stack(sun_vector(elevation, azimuth, plant.azimuth))
    dni = irradiance.dni(times, site, weather).to_numpy()
    distances = field_distances(N_FIELD_MIRRORS, scenario.mirror.spacing or DEFAULT_MIRROR_SPACING)
    sharing = np.nan_to_num(sharing_errors(times, site, plant, date, distances))
    sharing[:, distances == 0.0] = 0.0  # the central mirror's primary is the shared one
    angles = [two_axis_angles(elevation, azimuth, d, plant.tube_height, plant.azimuth) for d in distances]
    primary = np.stack([p for p, _ in angles], axis=1)  # (T, N) [rad]
    secondary = np.stack([q for _, q in angles], axis=1)
    out = {"dni_W_m2": dni, "mirror_distance_m": distances}
    for key, p in (("ideal", primary), ("shared", primary - sharing)):
        unhidden = _unhidden_share(sun, up, p, secondary, distances, plant.tube_height, conf, shading_every)
        lights = [  # the receiver's shadow is in the unhidden share, with the neighbours' (their union)
            attitude_light(sun, dni, up, p[:, k], secondary[:, k], float(d), plant.tube_height, conf, False)
            for k, d in enumerate(distances)
        ]
        out[f"power_{key}_unshaded_W"] = np.stack([light["power_W"] for light in lights], axis=1)
        out[f"power_{key}_W"] = out[f"power_{key}_unshaded_W"] * unhidden
        out[f"cosine_{key}"] = np.stack([light["cosine"] for light in lights], axis=1)
        out[f"unhidden_{key}"] = unhidden
    return out


def _day_rows(
    scenario, date: dt.date, day: int, step_minutes: float, indices: list[int], weather, every: int | None
) -> list[dict]:
    """The table's rows of one day (see :func:`field_light_days`), one per mirror; ``weather``: the
    scenario's weather file already read (None: clear sky); ``every``: shading's step in ``step_minutes``
    (None: no shading)."""
    start = pd.Timestamp(date).tz_localize(scenario.site.to_site().timezone)
    times = pd.date_range(start, start + pd.Timedelta(days=1), freq=pd.Timedelta(minutes=step_minutes))
    seconds = (times - start).total_seconds().to_numpy()
    light = field_light_instants(scenario, times, date, weather, every)
    rows = []
    for index in indices:
        e_ideal, e_shared, e_unshaded = (
            float(np.trapezoid(light[key][:, index], seconds))
            for key in ("power_ideal_W", "power_shared_W", "power_ideal_unshaded_W")
        )
        rows.append(
            {
                "day_of_year": day,
                "date": date.isoformat(),
                "mirror_index": index,
                "mirror_distance_m": float(light["mirror_distance_m"][index]),
                "light_energy_ideal_J": e_ideal,
                "light_energy_J": e_shared,
                "light_lost_shared_primary_J": e_ideal - e_shared,
                "light_lost_J": e_ideal - e_shared,
                "light_lost_fraction": (e_ideal - e_shared) / e_ideal if e_ideal > 0 else 0.0,
                "shading_lost_ideal_J": e_unshaded - e_ideal,
                "status": "ok",
            }
        )
    return rows


def _unhidden_share(sun, up, primary, secondary, distances, tube_height, conf, every: int | None) -> np.ndarray:
    """Share [-] of each field mirror (instants by mirrors) that neither shading (by the neighbours and the
    receiver) nor blocking hides, at the attitudes ``primary``, ``secondary`` [rad] (T, N): computed every
    ``every``-th instant with the sun ``up`` (and the day's first and last such), linear in the instant's
    index between; with ``every`` None the receiver's shadow only, at every instant; 1 with the sun down."""
    share = np.ones(primary.shape)
    lit = np.flatnonzero(up)
    if lit.size == 0:
        return share
    receiver = conf.receiver()
    width = receiver_width(receiver["tube_diameter"], receiver["secondary"])
    own = receiver_shadow_fraction(
        sun[:, lit].T[:, None, :],
        np.stack(mirror_normal(primary[lit], secondary[lit]), axis=-1),
        distances,
        tube_height,
        width,
        conf.mirror_width,
        conf.mirror_length,
    )  # (L, N), at every instant: a short band crossing the field, which a coarse step would miss
    share[lit] = 1.0 - own
    if every is None:
        return share

    def neighbours(coarse: np.ndarray) -> np.ndarray:
        normals = np.stack(mirror_normal(primary[coarse], secondary[coarse]), axis=-1)  # (K, N, 3)
        return row_losses(sun[:, coarse].T, normals, distances, conf.mirror_width, conf.mirror_length, only_lost=True)[
            "lost"
        ]

    share[lit] *= 1.0 - interpolated_at_coarse_instants(lit, every, neighbours)  # the two combined as independent
    return share
