"""The end-loss gain of two-axis end mirrors: lit length and energy on the tube, per instant, day and year.

A single-axis plant against one with two-axis end sections, both with shading and blocking between
neighbouring rows ([paper], eqs. 1-6).

Details: docs/light.md, ``heliostep.solar.endloss``.
"""

from __future__ import annotations

import datetime as dt
from collections.abc import Callable

import numpy as np
import pandas as pd

from heliostep.errors import InputError
from heliostep.solar.checks import as_float_array, check_positive, check_range
from heliostep.solar.field import PANEL_LENGTH
from heliostep.solar.irradiance import clear_sky_dni
from heliostep.solar.row_shading import interpolated_losses, shading_losses
from heliostep.solar.sun import Site, solar_position, sun_vector
from heliostep.solar.tracking import end_loss_length, single_axis_tilt


def single_axis_cosine(elevation, azimuth, mirror_distance, tube_height, plant_azimuth: float = 0.0):
    """Cosine of incidence on a single-axis row.

    Parameters
    ----------
    elevation, azimuth : array-like  [deg]
    mirror_distance : float or array-like  [m]
    tube_height : float  [m]
    plant_azimuth : float, default 0  [deg]

    Returns
    -------
    array  [-]
        S . n with n = (cos beta, 0, sin beta) ([paper], eq. 1), clipped at 0.
    """
    beta = as_float_array(single_axis_tilt(elevation, azimuth, mirror_distance, tube_height, plant_azimuth))
    sun_x, _, sun_z = (as_float_array(c) for c in sun_vector(elevation, azimuth, plant_azimuth))
    return np.clip(sun_x * np.cos(beta) + sun_z * np.sin(beta), 0.0, None)  # [paper], eq. 1; Lambert's law


def two_axis_cosine(elevation, azimuth, mirror_distance, tube_height, plant_azimuth: float = 0.0):
    """Cosine of incidence on a two-axis mirror aimed at the tube in its own cross-section.

    Returns
    -------
    array  [-]
        sqrt((1 + S . T) / 2), T = (-d, 0, h) / sqrt(d^2 + h^2): the normal bisects S and T
        ([paper], eqs. 3-6).
    """
    tube_height = check_positive(tube_height, "tube_height", "m")
    d = as_float_array(mirror_distance)
    sun_x, _, sun_z = (as_float_array(c) for c in sun_vector(elevation, azimuth, plant_azimuth))
    dot = (-d * sun_x + tube_height * sun_z) / np.hypot(d, tube_height)
    return np.sqrt(np.clip((1.0 + dot) / 2.0, 0.0, None)) * (sun_z > 0)  # cosine of half the angle S, T


def end_loss_power(
    elevation,
    azimuth,
    dni,
    plant_length,
    tube_height,
    mirror_distances,
    mirror_width,
    end_length,
    optical_efficiency: float = 1.0,
    plant_azimuth: float = 0.0,
    mirror_length: float = PANEL_LENGTH,
    shading: bool = True,
    losses: dict | None = None,
    receiver_width: float | None = None,
) -> dict:
    """Lit length and absorbed power of a plant with single-axis rows vs two-axis end mirrors.

    Parameters
    ----------
    elevation, azimuth : array-like  [deg]
        Apparent sun elevation and azimuth, one value per instant.
    dni : array-like  [W/m^2]
        Direct normal irradiance at the same instants.
    plant_length, tube_height : float  [m]
        L (> 2 ``end_length``) and h.
    mirror_distances : array-like  [m]
        Transverse positions d_i of the rows, each w = ``mirror_width`` [m] wide across the tube, > 0.
    end_length : float  [m]
        L_e, the length of each end section of two-axis mirrors, >= 0.
    optical_efficiency : float, default 1  [-]
        rho tau alpha (:func:`heliostep.solar.optics.optical_chain`).
    plant_azimuth : float, default 0  [deg]
    mirror_length : float, default 1.5 (Table 2's panel)  [m] of each two-axis mirror, contiguous.
    shading : bool, default True
        Shading and blocking (:func:`heliostep.solar.row_shading.shading_losses`, or ``losses``).
    receiver_width : float, optional  [m] across, for the receiver's own shadow; None: none.

    Returns
    -------
    dict of arrays (one value per instant; 0 or NaN while the sun is down)
        ``shift_min_m`` / ``shift_max_m``: min and max over the rows of |k| ([paper], eq. 2);
        ``unlit_length_m`` (= shift_min_m), ``lit_length_m`` (L - that);
        ``power_single_W``, ``power_two_axis_W``, ``end_spill_single_W`` (light a single-axis
        plant sends past the tube's end) [W]; ``gain`` = power_two_axis / power_single - 1;
        ``beam_rows_W`` / ``beam_end_sections_W``: the beam [W] the rows over L and the end sections
        collect; ``lost_single`` / ``lost_two_axis`` [-] per row (``row_shading.shading_losses``).
    """
    length, width, end, efficiency = _checked_plant(plant_length, mirror_width, end_length, optical_efficiency)
    elevation, azimuth, distances, irradiance = _instants_by_rows(elevation, azimuth, mirror_distances, dni)
    up = elevation[:, 0] > 0.0
    shift = np.abs(end_loss_length(elevation, azimuth, distances, tube_height, plant_azimuth))  # [paper], eq. 2
    shift = np.where(up[:, None], shift, np.nan)
    geometry = (distances, tube_height, plant_azimuth, width, mirror_length, receiver_width)
    cos_single, cos_two, losses = _unhidden_cosines(elevation, azimuth, geometry, shading, losses)
    figures = _plant_powers(irradiance, efficiency, width, length, end, shift, up, cos_single, cos_two)
    figures["lost_single"], figures["lost_two_axis"] = losses["single"], losses["two_axis"]
    return figures


def _plant_powers(irradiance, efficiency, width, length, end, shift, up, cos_single, cos_two) -> dict:
    """:func:`end_loss_power`'s powers [W] and lengths [m] from the DNI [W/m^2], rho tau alpha, w, L, L_e
    [m], the rows' shifts [m], the sun up, and the rows' unhidden cosines (instants by rows)."""
    on_tube_single = np.clip(length - shift, 0.0, None)  # the part of a row whose light lands on the tube
    middle = length - 2.0 * end
    overlap = np.clip(np.minimum(middle, length - end - shift), 0.0, None)  # [L_e + k, L - L_e + k] on [0, L]
    scale = irradiance * efficiency * width
    power_single = scale * np.nansum(cos_single * on_tube_single, axis=1)
    power_two = scale * np.nansum(cos_single * overlap + cos_two * 2.0 * end, axis=1)
    spill = scale * np.nansum(cos_single * np.minimum(shift, length), axis=1)
    figures = _end_loss_figures(up, shift, length, power_single, power_two, spill)
    beam = irradiance * width * up
    figures["beam_rows_W"] = beam * np.sum(cos_single, axis=1) * length
    figures["beam_end_sections_W"] = beam * np.sum(cos_two, axis=1) * 2.0 * end
    return figures


def _unhidden_cosines(elevation, azimuth, geometry, shading: bool, losses):
    """Cosines [-] of the single-axis rows and the two-axis end mirrors (instants by rows), times the share
    of each that neither shading nor blocking hides (with ``shading``: ``losses``, or
    :func:`heliostep.solar.row_shading.shading_losses` computed here), and the losses used; ``geometry``:
    the rows' distances, h, the plant's azimuth, w, l and the receiver's width."""
    distances, tube_height, plant_azimuth, width, length, receiver_width = geometry
    cos_single = single_axis_cosine(elevation, azimuth, distances, tube_height, plant_azimuth)
    cos_two = two_axis_cosine(elevation, azimuth, distances, tube_height, plant_azimuth)
    if losses is None and not shading:
        losses = {"single": np.zeros_like(cos_single), "two_axis": np.zeros_like(cos_two)}
    elif losses is None:
        row = (distances[0], tube_height, width, length, plant_azimuth, receiver_width)
        losses = shading_losses(elevation[:, 0], azimuth[:, 0], *row)
    if shading:
        cos_single = cos_single * (1.0 - losses["single"])  # the unhidden share of each row
        cos_two = cos_two * (1.0 - losses["two_axis"])
    return cos_single, cos_two, losses


def _end_loss_figures(
    up: np.ndarray,
    shift: np.ndarray,
    length: float,
    power_single: np.ndarray,
    power_two: np.ndarray,
    spill: np.ndarray,
) -> dict:
    """The figures :func:`end_loss_power` returns, from the instants with the sun *up*, the rows'
    shifts [m] (instants by rows), the plant length [m] and the powers [W] per instant."""
    with np.errstate(invalid="ignore", divide="ignore"):
        gain = np.where(power_single > 0, power_two / power_single - 1.0, np.nan)
        shift_min = np.where(up, np.nanmin(np.where(up[:, None], shift, np.inf), axis=1), np.nan)
        shift_max = np.where(up, np.nanmax(np.where(up[:, None], shift, -np.inf), axis=1), np.nan)
    return {
        "shift_min_m": shift_min,
        "shift_max_m": shift_max,
        "unlit_length_m": np.minimum(shift_min, length),
        "lit_length_m": np.clip(length - shift_min, 0.0, None),
        "power_single_W": np.where(up, power_single, 0.0),
        "power_two_axis_W": np.where(up, power_two, 0.0),
        "end_spill_single_W": np.where(up, spill, 0.0),
        "gain": gain,
    }


def _checked_plant(plant_length, mirror_width, end_length, optical_efficiency) -> tuple[float, float, float, float]:
    """Length L [m], row width w [m], end length L_e [m] and optical efficiency [-] of
    :func:`end_loss_power`, checked (two end sections shorter than the plant)."""
    length = check_positive(plant_length, "plant_length", "m")
    width = check_positive(mirror_width, "mirror_width", "m")
    end = check_range(end_length, "end_length", 0.0, np.inf, "m")
    if not 2.0 * end < length:
        raise InputError(f"end_length {end:g} m: two end sections must be shorter than plant_length {length:g} m")
    efficiency = check_range(optical_efficiency, "optical_efficiency", 0.0, 1.0, "-")
    return length, width, end, efficiency


def _instants_by_rows(elevation, azimuth, mirror_distances, dni) -> tuple[np.ndarray, ...]:
    """Sun elevation and azimuth [deg] as columns (one row per instant), the rows' distances [m] as
    one row, and the DNI [W/m^2] per instant, checked (finite, >= 0, one per instant)."""
    elevation = np.atleast_1d(as_float_array(elevation))[:, None]
    azimuth = np.atleast_1d(as_float_array(azimuth))[:, None]
    distances = np.atleast_1d(as_float_array(mirror_distances)).ravel()[None, :]
    irradiance = np.atleast_1d(as_float_array(dni))
    if irradiance.shape != elevation[:, 0].shape or np.any(irradiance < 0) or not np.all(np.isfinite(irradiance)):
        raise InputError("dni: expected one finite value >= 0 [W/m^2] per instant")
    return elevation, azimuth, distances, irradiance


def _year_grid(site: Site, year: int, step_minutes: float, days=None) -> tuple[pd.DatetimeIndex, np.ndarray]:
    """Instants every ``step_minutes`` from each chosen day's local midnight to the next, and their day of year."""
    n_days = (dt.date(year + 1, 1, 1) - dt.date(year, 1, 1)).days
    chosen = np.arange(1, n_days + 1) if days is None else np.asarray(list(days), dtype=int)
    if chosen.size == 0 or chosen.min() < 1 or chosen.max() > n_days:
        raise InputError(f"days: expected days of year 1 .. {n_days}, got {days!r}")
    step = pd.Timedelta(minutes=check_positive(step_minutes, "step_minutes", "min"))
    stamps, labels = [], []
    for day in chosen:
        date = dt.date(year, 1, 1) + dt.timedelta(days=int(day) - 1)
        midnight = pd.Timestamp(date).tz_localize(site.timezone)
        following = pd.Timestamp(date + dt.timedelta(days=1)).tz_localize(site.timezone)  # 23 or 25 h on DST days
        grid = pd.date_range(midnight, following, freq=step, inclusive="left")
        stamps.append(grid)
        labels.append(np.full(len(grid), int(day)))
    times = stamps[0].append(stamps[1:]) if len(stamps) > 1 else stamps[0]
    return times, np.concatenate(labels)


def largest_shift(
    site: Site,
    year: int,
    tube_height: float,
    mirror_distances,
    min_elevation: float = 5.0,
    step_minutes: float = 20.0,
    plant_azimuth: float = 0.0,
) -> float:
    """Largest |k| over a year and the rows while the sun is above ``min_elevation`` [m].

    The paper sizes the two-axis end sections by it ([paper], Section 3). Near the horizon
    |k| grows without bound when the sun stands along the tube, hence ``min_elevation`` [deg].
    """
    times, _ = _year_grid(site, year, step_minutes)
    sun = solar_position(times, site.latitude, site.longitude, site.altitude)
    elevation, azimuth = sun["apparent_elevation"].to_numpy(), sun["azimuth"].to_numpy()
    keep = elevation > min_elevation
    distances = np.atleast_1d(as_float_array(mirror_distances)).ravel()[None, :]
    shift = end_loss_length(elevation[keep, None], azimuth[keep, None], distances, tube_height, plant_azimuth)
    return float(np.max(np.abs(shift)))


def end_loss_days(
    site: Site,
    year: int,
    plant_length: float,
    tube_height: float,
    mirror_distances,
    mirror_width: float,
    end_length: float,
    optical_efficiency: float = 1.0,
    days=None,
    step_minutes: float = 5.0,
    plant_azimuth: float = 0.0,
    mirror_length: float = PANEL_LENGTH,
    shading: bool = True,
    shading_step_minutes: float = 30.0,
    receiver_width: float | None = None,
    progress: Callable[[int], object] | None = None,
) -> pd.DataFrame:
    """Energy on the tube per day, single-axis plant vs two-axis end mirrors, clear sky (pvlib Ineichen).

    Parameters
    ----------
    site : Site
    year : int
    plant_length, tube_height, mirror_distances, mirror_width, end_length, optical_efficiency : as
        :func:`end_loss_power`.
    days : iterable of int, optional: days of the year (default every day).
    step_minutes : float, default 5  [min]: of the sun's positions (trapezoidal integration over the day).
    plant_azimuth : float, default 0  [deg]
    mirror_length, shading, receiver_width : as :func:`end_loss_power`.
    shading_step_minutes : float, default 30  [min]
        The two-axis mirrors' shading and blocking (their polygons: the cost) every this many minutes
        of daylight, interpolated between (:func:`heliostep.solar.row_shading.interpolated_losses`;
        ``tests/solar/test_endloss.py`` bounds what this moves against every instant).
    progress : callable, optional: called with a number of days as their losses (the cost) are done.

    Returns
    -------
    pandas.DataFrame
        Indexed by ``day_of_year``: ``date``, ``energy_single_J``, ``energy_two_axis_J``,
        ``end_spill_single_J`` [J], ``gain`` (energy_two_axis / energy_single - 1) [-],
        ``unlit_length_noon_m`` and ``lit_length_noon_m`` at the day's highest sun [m], and ``gain_noon``
        (power_two_axis / power_single - 1 at that instant) [-].
    """
    times, labels = _year_grid(site, year, step_minutes, days)
    sun = solar_position(times, site.latitude, site.longitude, site.altitude)
    elevation, azimuth = sun["apparent_elevation"].to_numpy(), sun["azimuth"].to_numpy()
    dni = clear_sky_dni(times, site).to_numpy()
    geometry = (mirror_distances, tube_height, mirror_width, mirror_length, plant_azimuth, receiver_width)
    steps = (step_minutes, shading_step_minutes) if shading else None
    losses = _grid_losses(elevation, azimuth, labels, geometry, steps, progress)
    plant = (plant_length, tube_height, mirror_distances, mirror_width, end_length, optical_efficiency)
    power = end_loss_power(
        elevation, azimuth, dni, *plant, plant_azimuth, mirror_length, shading, losses, receiver_width
    )
    frame = _power_frame(times, elevation, power)
    table = pd.DataFrame([_day_row(day, group) for day, group in frame.groupby(labels, sort=True)])
    table = table.set_index("day_of_year")
    table.attrs["end_length_m"] = float(end_length)
    return table


def _grid_losses(elevation, azimuth, labels, geometry, steps, progress):
    """The rows' losses over the grid: :func:`heliostep.solar.row_shading.interpolated_losses` with ``steps``,
    (step, shading step) [min]; None without shading (``steps`` None), ``progress`` then told of all the days."""
    if steps is None:
        if progress is not None:
            progress(len(np.unique(labels)))
        return None
    every = max(1, int(round(check_positive(steps[1], "shading_step_minutes", "min") / steps[0])))
    return interpolated_losses(elevation, azimuth, labels, every, *geometry, progress=progress)


def _power_frame(times: pd.DatetimeIndex, elevation: np.ndarray, power: dict) -> pd.DataFrame:
    """:func:`end_loss_power`'s powers [W] and lengths [m] by instant, with the sun's elevation [deg] and
    the seconds since the first instant."""
    frame = pd.DataFrame(
        {
            k: power[k]
            for k in ("power_single_W", "power_two_axis_W", "end_spill_single_W", "unlit_length_m", "lit_length_m")
        },
        index=times,
    )
    frame["elevation"] = elevation
    frame["seconds"] = (times - times[0]).total_seconds()
    return frame


def _day_row(day, group: pd.DataFrame) -> dict:
    """One day's row of :func:`end_loss_days` from its instants' powers [W], lengths [m] and elevations."""
    t = group["seconds"].to_numpy()
    energy = {
        name: float(np.trapezoid(group[f"{name}_W"].to_numpy(), t))
        for name in ("power_single", "power_two_axis", "end_spill_single")
    }
    noon = group.iloc[int(np.argmax(group["elevation"].to_numpy()))]
    noon_single, noon_two = float(noon["power_single_W"]), float(noon["power_two_axis_W"])
    return {
        "day_of_year": int(day),
        "date": group.index[0].date().isoformat(),
        "energy_single_J": energy["power_single"],
        "energy_two_axis_J": energy["power_two_axis"],
        "end_spill_single_J": energy["end_spill_single"],
        "gain": energy["power_two_axis"] / energy["power_single"] - 1.0 if energy["power_single"] > 0 else np.nan,
        "unlit_length_noon_m": float(noon["unlit_length_m"]),
        "lit_length_noon_m": float(noon["lit_length_m"]),
        "gain_noon": noon_two / noon_single - 1.0 if noon_single > 0 else np.nan,
    }
