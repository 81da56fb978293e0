"""From a scenario's ``wind`` section to the wind over the window: its speed, the stow plan, the moment signal.

The speed is piecewise linear between knots; the moment on the mechanics' ``m_ext`` is piecewise
constant, evaluated on the commanded panel angle, never understating the continuous one.

Details: docs/physics.md, ``heliostep.drive.wind_load``.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from heliostep.drive.wind import air_density, cross_wind_speed, external_moment
from heliostep.errors import InputError
from heliostep.scenario import Scenario
from heliostep.solar.irradiance import WeatherFile

__all__ = [
    "WindKnots",
    "WindSignal",
    "commanded_panel_angle",
    "moment_signal",
    "panel_axis_azimuth",
    "wind_speed_knots",
    "wind_weather_path",
]


@dataclass(frozen=True)
class WindSignal:
    """The moment on the mechanics' ``m_ext`` [N.m]: ``values[0]`` before ``times[0]``, ``values[k + 1]``
    from ``times[k]`` on; and the mean wind speed's knots (``speed_times`` [s], ``speed`` [m/s])."""

    times: np.ndarray
    values: np.ndarray
    speed_times: np.ndarray
    speed: np.ndarray
    #: the commanded panel angle [rad] over each hold (``angles[0]`` before ``times[0]``)
    angles: np.ndarray

    def peak_moment(self) -> float:
        """The largest |m_ext| over the window [N.m]."""
        return float(np.max(np.abs(self.values)))

    def worst_holding_instant(self, pinion_radius: float, lever_arm: float) -> dict:
        """The hold where the drive's holding moment on the panel axis is smallest against the wind:
        the smallest g(theta_p) / |m_ext| with g = s / (r cos^2 theta_p) ([paper], eq. 15).

        Returns
        -------
        dict
            ``time_s`` (the hold's start) [s], ``drive_ratio`` [-], ``moment_Nm`` (m_ext) [N.m]
            and ``peak_moment_Nm`` [N.m]; ``time_s`` None without wind (every moment 0).
        """
        ratio = lever_arm / (pinion_radius * np.cos(self.angles) ** 2)  # [paper], eq. 15
        magnitude = np.abs(self.values)
        record = {"time_s": None, "drive_ratio": None, "moment_Nm": 0.0, "peak_moment_Nm": self.peak_moment()}
        if not np.any(magnitude > 0.0):
            return record
        with np.errstate(divide="ignore"):
            k = int(np.argmin(np.where(magnitude > 0.0, ratio / magnitude, np.inf)))
        starts = np.concatenate([[0.0], self.times])
        return {
            **record,
            "time_s": float(starts[k]),
            "drive_ratio": float(ratio[k]),
            "moment_Nm": float(self.values[k]),
        }


def wind_weather_path(scenario: Scenario) -> Path:
    """The scenario's ``wind.weather_file``, relative to the scenario's folder unless absolute."""
    path = Path(str(scenario.wind.weather_file)).expanduser()
    return path if path.is_absolute() else Path(scenario.folder) / path


@dataclass(frozen=True)
class WindKnots:
    """The wind over the window, linear between knots: ``times`` [s from the start], mean ``speed``
    [m/s], the air's ``temperature`` [degC] (None: the scenario's ``wind.air_temperature`` or
    the ISA's) and the ``direction`` the wind blows from [deg clockwise from north] (None, or NaN
    at a knot: normal to the panel's axis, the worst case)."""

    times: np.ndarray
    speed: np.ndarray
    temperature: np.ndarray | None = None
    direction: np.ndarray | None = None

    def cross_speed(self, times, axis_azimuth: float) -> np.ndarray:
        """The wind's component normal to an axis along ``axis_azimuth`` [deg] at ``times`` [s], signed
        [m/s] (:func:`heliostep.drive.wind.cross_wind_speed` at the knots, linear between them)."""
        at_knots = cross_wind_speed(self.speed, self.direction, axis_azimuth)
        return np.interp(np.asarray(times, dtype=float), self.times, np.broadcast_to(at_knots, self.times.shape))

    def density(self, scenario: Scenario, times) -> np.ndarray:
        """Air density [kg/m^3] at ``times`` [s]: the site's altitude at the file's temperature where
        it has one, else at ``wind.air_temperature``, else the ISA's (:func:`heliostep.drive.wind.air_density`)."""
        altitude, given = scenario.site.altitude, scenario.wind.air_temperature
        times = np.asarray(times, dtype=float)
        if given is None and self.temperature is not None and np.all(np.isfinite(self.temperature)):
            return air_density(altitude, np.interp(times, self.times, self.temperature))
        return np.broadcast_to(air_density(altitude, given), times.shape)


def wind_speed_knots(scenario: Scenario, start: pd.Timestamp, duration: float) -> WindKnots | None:
    """The mean wind speed's knots over the window (:class:`WindKnots`); None with a constant moment
    (no speed). InputError names the file and key when a weather file has no wind speed over the window."""
    wind = scenario.wind
    given = None if wind.direction is None else float(wind.direction)
    if wind.speed is not None:
        times = np.array([0.0, duration])
        return WindKnots(times, np.array([wind.speed, wind.speed]), None, _constant(given, times))
    if wind.profile is not None:
        t = np.array([p[0] for p in wind.profile], dtype=float)
        v = np.array([p[1] for p in wind.profile], dtype=float)
        inside = t[(t > 0.0) & (t < duration)]
        times = np.concatenate([[0.0], inside, [duration]])
        return WindKnots(times, np.interp(times, t, v), None, _constant(given, times))
    if wind.weather_file is None:
        return None
    path = wind_weather_path(scenario)
    weather = WeatherFile.read(path, scenario.site.to_site())
    end = start + pd.Timedelta(seconds=duration)
    stamps = pd.date_range(start.floor("h"), end.ceil("h"), freq="h")
    instants = pd.DatetimeIndex([start, *[s for s in stamps if start < s < end], end])
    series = weather.series(instants)
    speed = None if series.wind_speed is None else series.wind_speed.to_numpy(dtype=float)
    if speed is None or not np.all(np.isfinite(speed)):
        raise InputError(
            f"{scenario.source}: wind.weather_file: {path} has no wind speed (wind_speed missing or "
            f"marked missing) over the window {start} - {end}; expected a speed [m/s] at every stamp"
        )
    temperature = None if series.air_temperature is None else series.air_temperature.to_numpy(dtype=float)
    times = (instants - start).total_seconds().to_numpy(dtype=float)
    direction = None if series.wind_direction is None else series.wind_direction.to_numpy(dtype=float)
    return WindKnots(times, speed, temperature, direction if given is None else _constant(given, times))


def _constant(direction: float | None, times: np.ndarray) -> np.ndarray | None:
    return None if direction is None else np.full(times.shape, direction)


def panel_axis_azimuth(scenario: Scenario) -> float:
    """The driven panel's axis [deg clockwise from north]: the tube's azimuth for the primary axis, 90 deg
    more for the secondary (docs/physics.md, frames: the primary turns about the tube's y, the
    secondary about an axis across it)."""
    tube = scenario.plant.to_plant().azimuth
    return float(tube if scenario.mirror.axis == "primary" else tube + 90.0)


def commanded_panel_angle(rotor_angle, panel_start: float, pinion_radius: float, lever_arm: float) -> np.ndarray:
    """The panel angle [rad] of a rotor angle [rad] (0 at ``panel_start``), [paper] eq. 14 inverted."""
    return np.arctan(np.tan(panel_start) + np.asarray(rotor_angle) * pinion_radius / lever_arm)  # [paper], eq. 14


def moment_signal(
    scenario: Scenario,
    knots: WindKnots,
    step_times: np.ndarray,
    commanded_panel,
    duration: float,
) -> WindSignal:
    """The ``m_ext`` signal of the wind's knots on the commanded panel angle (the module's docstring).

    Parameters
    ----------
    scenario : Scenario
    knots : WindKnots
        :func:`wind_speed_knots`.
    step_times : array  [s]
        The drive's step instants.
    commanded_panel : callable
        The commanded panel angle [rad] from each time [s] on (right-continuous at the steps).
    duration : float  [s]
    """
    wind, optics = scenario.wind, scenario.optics
    t_knots, v_knots = knots.times, knots.speed
    axis = panel_axis_azimuth(scenario)
    grid = np.arange(0.0, duration, wind.update_interval)
    changes = np.unique(np.concatenate([step_times, t_knots, grid]))
    changes = changes[(changes > 0.0) & (changes < duration)]
    starts = np.concatenate([[0.0], changes])
    ends = np.concatenate([changes, [duration]])
    angle = commanded_panel(starts)  # held over each interval (the command changes only at steps)

    def at(times):
        speed = knots.cross_speed(times, axis)  # the component normal to the axis
        density = knots.density(scenario, times)
        return external_moment(speed, angle, optics.aperture_area, optics.mirror_width, density, wind.gust_factor)

    first, last = at(starts), at(ends)
    values = np.where(np.abs(last) > np.abs(first), last, first)
    return WindSignal(
        changes, np.asarray(values, dtype=float), np.asarray(t_knots), np.asarray(v_knots), np.asarray(angle)
    )
