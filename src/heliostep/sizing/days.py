"""The days ``heliostep size`` co-simulates: the year's windiest and the sun's fastest, found, not assumed.

Details: docs/sizing.md, ``heliostep.sizing.days``.
"""

from __future__ import annotations

import datetime as dt
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from heliostep.drive.wind_load import wind_weather_path
from heliostep.errors import InputError
from heliostep.scenario import Scenario
from heliostep.solar.irradiance import WeatherFile
from heliostep.solar.sun import solar_position
from heliostep.solar.tracking import two_axis_angles

__all__ = [
    "ALL_DAYS",
    "DAYS_IN_YEAR",
    "FASTEST_DAY_COUNT",
    "PEAK_SEPARATION_DAYS",
    "WINDIEST_DAY_COUNT",
    "ChosenDay",
    "DaySelection",
    "date_of",
    "day_windows",
    "fastest_days",
    "panel_angle_range",
    "panel_rates",
    "rate_grid_step",
    "select_days",
    "window_wind_speeds",
    "windiest_days",
]

#: The days of the year a selection ranges over (day of year 1 .. 365).
DAYS_IN_YEAR = 365
#: The word ``--days`` takes for every day of the year.
ALL_DAYS = "all"
#: How many of the annual rate curve's peaks are simulated.
FASTEST_DAY_COUNT = 2
#: A peak of the annual rate curve is the highest within this many days on either side [days].
PEAK_SEPARATION_DAYS = 15
#: How many of the weather file's windiest days are simulated.
WINDIEST_DAY_COUNT = 3


@dataclass(frozen=True)
class ChosenDay:
    """A day of the selection and why it was chosen."""

    day_of_year: int
    date: dt.date
    reasons: tuple[str, ...]
    panel_rate_deg_s: float | None = None  # the largest |d theta_p/dt| in the window [deg/s]
    wind_speed_m_s: float | None = None  # the largest mean wind speed in the window [m/s]

    def record(self) -> dict:
        return {
            "day_of_year": self.day_of_year,
            "date": self.date.isoformat(),
            "reasons": list(self.reasons),
            "panel_rate_deg_s": self.panel_rate_deg_s,
            "wind_speed_m_s": self.wind_speed_m_s,
        }


@dataclass(frozen=True)
class DaySelection:
    """The days to simulate (sorted), each with its reasons, and the criterion in words."""

    days: list[int]
    chosen: list[ChosenDay] = field(default_factory=list)
    criterion: str = ""
    kind: str = "selected"  # "selected" (the fastest and windiest), "all" (365) or "given"

    def record(self) -> dict:
        return {"kind": self.kind, "criterion": self.criterion, "days": [day.record() for day in self.chosen]}


def date_of(year: int, day_of_year: int) -> dt.date:
    """The date of a year's day (1 for 1 January)."""
    return dt.date(year, 1, 1) + dt.timedelta(days=day_of_year - 1)


#: :func:`day_windows` of the last few (window, site) pairs: a sunrise-to-sunset window's 365 days take
#: 365 SPA sunrise and sunset searches, and a sizing asks for them twice (its days, its stow angles).
_WINDOWS_CACHE: dict[tuple[str, str], list] = {}
_WINDOWS_CACHE_SIZE = 4


def day_windows(scenario: Scenario) -> list[tuple[pd.Timestamp, pd.Timestamp] | None]:
    """The scenario's window on each day 1..365 of its year (None where it does not exist that day:
    no sunrise, a clock time skipped by a daylight-saving change). They depend on its window and site
    alone (:meth:`heliostep.scenario.Scenario.window_bounds`): kept for the same pair."""
    key = (scenario.window.model_dump_json(), scenario.site.model_dump_json())
    if key not in _WINDOWS_CACHE:
        if len(_WINDOWS_CACHE) >= _WINDOWS_CACHE_SIZE:
            _WINDOWS_CACHE.pop(next(iter(_WINDOWS_CACHE)))
        _WINDOWS_CACHE[key] = _year_windows(scenario)
    return list(_WINDOWS_CACHE[key])


def _year_windows(scenario: Scenario) -> list[tuple[pd.Timestamp, pd.Timestamp] | None]:
    year = scenario.window.date.year
    windows: list[tuple[pd.Timestamp, pd.Timestamp] | None] = []
    for day in range(1, DAYS_IN_YEAR + 1):
        window = scenario.window.model_copy(update={"date": date_of(year, day)})
        try:
            windows.append(scenario.model_copy(update={"window": window}).window_bounds())
        except InputError:
            windows.append(None)
    return windows


def rate_grid_step(duration: float) -> float:
    """The grid of the rate's differences [s]: a twentieth of the window, within 10 s .. 120 s."""
    return float(np.clip(duration / 20.0, 10.0, 120.0))


def _ideal_angles(scenario: Scenario, windows: Sequence[tuple[pd.Timestamp, pd.Timestamp] | None]):
    """The ideal panel angle [rad] on every day's window grid (:func:`rate_grid_step`, both ends included),
    in one SPA call: (owner day index, seconds from the first stamp, apparent elevation [deg], angle), or
    None when no day has a window."""
    stamps, owners = [], []
    for day, window in enumerate(windows):
        if window is None:
            continue
        start, end = window
        duration = (end - start).total_seconds()
        offsets = np.arange(0.0, duration, rate_grid_step(duration))
        offsets = np.append(offsets, duration)
        stamps.append(start + pd.to_timedelta(offsets, unit="s"))
        owners.append(np.full(offsets.size, day))
    if not stamps:
        return None
    index = stamps[0].append(stamps[1:]) if len(stamps) > 1 else stamps[0]
    site, plant, mirror = scenario.site.to_site(), scenario.plant.to_plant(), scenario.mirror
    sun = solar_position(index, site.latitude, site.longitude, site.altitude)
    elevation = sun["apparent_elevation"].to_numpy()
    primary, secondary = two_axis_angles(
        elevation, sun["azimuth"].to_numpy(), mirror.mirror_distance, plant.tube_height, plant.azimuth
    )
    angle = np.asarray(secondary if mirror.axis == "secondary" else primary, dtype=float)
    seconds = (index - index[0]).total_seconds().to_numpy()
    return np.concatenate(owners), seconds, elevation, angle


def panel_rates(scenario: Scenario, windows: Sequence[tuple[pd.Timestamp, pd.Timestamp] | None]) -> np.ndarray:
    """The largest rate of the ideal panel angle within each day's window [rad/s] (NaN: no window,
    or the sun never up at two neighbouring grid points); one SPA call for every day's grid."""
    rates = np.full(len(windows), np.nan)
    grid = _ideal_angles(scenario, windows)
    if grid is None:
        return rates
    owner, seconds, elevation, angle = grid
    pair = (owner[1:] == owner[:-1]) & (elevation[1:] > 0.0) & (elevation[:-1] > 0.0)
    rate = np.abs(np.diff(angle)) / np.diff(seconds)
    found = owner[1:][pair]
    np.fmax.at(rates, found, rate[pair])  # NaN where no pair: fmax keeps the number
    return rates


def panel_angle_range(scenario: Scenario) -> tuple[float, float] | None:
    """The least and largest ideal panel angle [rad] within the scenario's window over the 365 days of its
    year, the sun up (the grid of :func:`panel_rates`, both ends of each window on it); None when the sun is
    never up in the window. The angles a stow move may start from on any day (:mod:`heliostep.sizing.stow`)."""
    grid = _ideal_angles(scenario, day_windows(scenario))
    if grid is None:
        return None
    _, _, elevation, angle = grid
    up = angle[elevation > 0.0]
    return (float(np.min(up)), float(np.max(up))) if up.size else None


def fastest_days(rates: np.ndarray, count: int = FASTEST_DAY_COUNT, separation: int = PEAK_SEPARATION_DAYS):
    """The ``count`` highest peaks of the annual rate curve (day of year, 1-based): days whose rate is
    the highest within ``separation`` days on either side, the year a circle; ties to the earlier day."""
    values = np.where(np.isfinite(rates), rates, -np.inf)
    n = values.size
    peaks = []
    for k in range(n):
        if not np.isfinite(values[k]):
            continue
        around = values[[(k + j) % n for j in range(-separation, separation + 1)]]
        earlier = values[[(k - j) % n for j in range(1, separation + 1)]]
        if values[k] >= around.max() and not np.any(earlier == values[k]):
            peaks.append(k)
    peaks.sort(key=lambda k: (-values[k], k))
    return [k + 1 for k in peaks[:count]]


def _window_instants(window: tuple[pd.Timestamp, pd.Timestamp]) -> pd.DatetimeIndex:
    """A window's ends and the whole hours inside it: where a linear interpolant has its largest value."""
    start, end = window
    hours = pd.date_range(start.ceil("h"), end.floor("h"), freq="h")
    return pd.DatetimeIndex([start, *[h for h in hours if start < h < end], end])


def _largest_speeds(weather: WeatherFile, instants: pd.DatetimeIndex, owner: np.ndarray, days: int) -> np.ndarray:
    """The largest speed per owner day of ``instants`` (NaN where any is missing); InputError when the
    file does not cover them."""
    series = weather.series(instants)
    speeds = np.full(days, np.nan)
    if series.wind_speed is None:
        return speeds
    frame = pd.DataFrame({"day": owner, "speed": series.wind_speed.to_numpy(dtype=float)})
    grouped = frame.groupby("day")["speed"]
    largest = grouped.max().where(grouped.apply(lambda v: bool(np.all(np.isfinite(v)))))
    speeds[largest.index.to_numpy()] = largest.to_numpy()
    return speeds


def window_wind_speeds(scenario: Scenario, windows: Sequence[tuple[pd.Timestamp, pd.Timestamp] | None]) -> np.ndarray:
    """The largest mean wind speed within each day's window [m/s] (the weather file's, linear between its
    stamps: the largest is at a whole hour inside the window or at an end); NaN where the file does not
    cover the window or marks the speed missing. One evaluation of the file for every day when it covers
    them all, else day by day."""
    weather = WeatherFile.read(wind_weather_path(scenario), scenario.site.to_site())
    parts = [(day, _window_instants(window)) for day, window in enumerate(windows) if window is not None]
    if not parts:
        return np.full(len(windows), np.nan)
    owner = np.concatenate([np.full(len(instants), day) for day, instants in parts])
    instants = parts[0][1].append([instants for _, instants in parts[1:]])
    try:
        return _largest_speeds(weather, instants, owner, len(windows))
    except InputError:  # the file does not cover every day: those it covers, one by one
        speeds = np.full(len(windows), np.nan)
        for day, day_instants in parts:
            try:
                speeds[day] = _largest_speeds(weather, day_instants, np.zeros(len(day_instants), int), 1)[0]
            except InputError:
                continue
        return speeds


def windiest_days(speeds: np.ndarray, count: int = WINDIEST_DAY_COUNT) -> list[int]:
    """The ``count`` days (day of year) of the highest speeds; ties to the earlier day."""
    order = [k for k in np.argsort(-np.where(np.isfinite(speeds), speeds, -np.inf), kind="stable")]
    return [int(k) + 1 for k in order if np.isfinite(speeds[k])][:count]


def _criterion(has_weather: bool) -> str:
    fastest = (
        f"the sun's fastest days: the {FASTEST_DAY_COUNT} highest peaks (the highest within "
        f"{PEAK_SEPARATION_DAYS} days either side) of the year's curve of the ideal panel angle's largest "
        "rate |d theta_p/dt| within the window (NREL SPA, the mirror's two-axis law)"
    )
    if not has_weather:
        return fastest + "; no weather file, so no windiest days (the wind is the same every day)"
    return (
        f"{fastest}, among the days the weather file covers; and the year's windiest days: the "
        f"{WINDIEST_DAY_COUNT} days with the highest mean wind speed within the window in the weather file"
    )


def _taken(scenario: Scenario, days: Sequence[int] | str) -> DaySelection:
    """``"all"`` or the given days, as they are."""
    year = scenario.window.date.year
    if isinstance(days, str):
        if days != ALL_DAYS:
            raise InputError(f"--days {days!r}: expected days of the year (1..365) or {ALL_DAYS!r}")
        every = list(range(1, DAYS_IN_YEAR + 1))
        chosen = [ChosenDay(d, date_of(year, d), ("every day of the year (--days all)",)) for d in every]
        return DaySelection(every, chosen, "every day of the year (--days all)", "all")
    given = sorted(set(int(d) for d in days))
    chosen = [ChosenDay(d, date_of(year, d), ("given (--days)",)) for d in given]
    return DaySelection(given, chosen, "the days given (--days)", "given")


def _covered_speeds(scenario: Scenario, windows) -> np.ndarray:
    """:func:`window_wind_speeds`, InputError naming the file when it has a speed on no day."""
    speeds = window_wind_speeds(scenario, windows)
    if not np.any(np.isfinite(speeds)):
        raise InputError(
            f"{scenario.source}: wind.weather_file: {wind_weather_path(scenario)} has no wind speed within the window "
            f"on any day it covers; expected a speed [m/s] at its stamps"
        )
    return speeds


def select_days(scenario: Scenario, days: Sequence[int] | str = ()) -> DaySelection:
    """The days to simulate: ``days`` as given, every day with ``"all"``, else the module's selection. With
    a weather file only days it covers (with a wind speed in the window) can be simulated: a given day it
    does not cover is an InputError naming the file, and the fastest days are sought among those it covers."""
    has_weather = scenario.wind.weather_file is not None
    if days:
        selection = _taken(scenario, days)
        if has_weather:
            speeds = _covered_speeds(scenario, day_windows(scenario))
            missing = [d for d in selection.days if not np.isfinite(speeds[d - 1])]
            if missing:
                raise InputError(
                    f"{scenario.source}: wind.weather_file: {wind_weather_path(scenario)} has no wind speed within the "
                    f"window on day(s) {missing[:10]}{' ...' if len(missing) > 10 else ''} of --days"
                )
        return selection
    year = scenario.window.date.year
    windows = day_windows(scenario)
    rates = panel_rates(scenario, windows)
    speeds = _covered_speeds(scenario, windows) if has_weather else np.full(len(windows), np.nan)
    if has_weather:
        rates = np.where(np.isfinite(speeds), rates, np.nan)  # only the days the file covers
    reasons: dict[int, list[str]] = {}
    for rank, day in enumerate(fastest_days(rates), start=1):
        text = f"sun's fastest #{rank}: the panel turns at up to {np.degrees(rates[day - 1]):.4g} deg/s in the window"
        reasons.setdefault(day, []).append(text)
    for rank, day in enumerate(windiest_days(speeds) if has_weather else [], start=1):
        text = f"windiest #{rank}: mean wind up to {speeds[day - 1]:.3g} m/s in the window (weather file)"
        reasons.setdefault(day, []).append(text)
    if not reasons:
        raise InputError(f"{scenario.source}: window: the sun is not up in the window on any day of {year}")
    chosen = [
        ChosenDay(
            day,
            date_of(year, day),
            tuple(reasons[day]),
            float(np.degrees(rates[day - 1])) if np.isfinite(rates[day - 1]) else None,
            float(speeds[day - 1]) if np.isfinite(speeds[day - 1]) else None,
        )
        for day in sorted(reasons)
    ]
    return DaySelection(sorted(reasons), chosen, _criterion(has_weather))
