"""Light on the tube and energy per run, from a stored trace, its metadata and the scenario.

The ideal, reference and actual attitudes of the mirror compared over the window; their differences
split into the shared primary, the reference law and the stepping. :class:`LightIntegrals`
accumulates the figures block by block, so a streamed trace is read one row group at a time.

Details: docs/light.md, ``heliostep.results.light.on_tube``.
"""

from __future__ import annotations

from collections.abc import Collection, Mapping
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from heliostep.results.light.mirror_power import attitude_light
from heliostep.results.light.notes import light_notes
from heliostep.results.light.rows import RowMarks, corrections, swing_rows
from heliostep.results.light.sun_grid import SUN_GRID_S, grid_slice, grid_span, sun_grid, window_sun_grid
from heliostep.results.light.sun_grid_image import interpolated_image
from heliostep.solar import irradiance

#: Step of the central difference of the cosine in the driven angle [rad]: its error is
#: eps^2/6 of the third derivative (< 1e-12), its rounding 1e-16 / eps (1e-10), both far below the figure.
COSINE_STEP = 1e-6


def _weather_path(scenario):
    path, folder = scenario.optics.weather_file, getattr(scenario, "folder", None)
    if path is None:
        return None
    return Path(path) if Path(path).is_absolute() or folder is None else Path(folder) / path


def read_weather_file(scenario) -> irradiance.WeatherFile | None:
    """A scenario's weather file (its path relative to the scenario's folder) read and checked for its
    site, or None for clear sky; an InputError names the file and key (:func:`load_weather` also
    checks it covers the window)."""
    path = _weather_path(scenario)
    return None if path is None else irradiance.WeatherFile.read(path, scenario.site.to_site())


def load_weather(scenario) -> irradiance.WeatherFile | None:
    """A scenario's weather file, read once and checked for its window, before simulating
    (None for clear sky); the run passes it on to the light figures. It carries the file's wind
    too (:meth:`heliostep.solar.irradiance.WeatherFile.series`: DNI and wind on a UTC index).

    Raises
    ------
    InputError
        Naming the file and the key (``weather_file``, ``latitude``, ``longitude``, ``dni``,
        ``window``) when the file cannot be read, is for another site, or does not cover the
        window (:mod:`heliostep.solar.irradiance`).
    """
    weather = read_weather_file(scenario)
    if weather is None:
        return None
    start, end = scenario.window_bounds()
    seconds = np.append(np.arange(0.0, (end - start).total_seconds(), 1800.0), (end - start).total_seconds())
    weather.at(start + pd.to_timedelta(seconds, unit="s"))  # covers the window, or InputError
    return weather


def _weather(scenario, weather):
    """The light figures' DNI source: ``weather`` (already read), else the scenario's file (read now) or None."""
    return weather if weather is not None else _weather_path(scenario)


def light_timeseries(trace: pd.DataFrame, metadata: Mapping, scenario, weather=None) -> pd.DataFrame:
    """Power on the tube at every row of the trace for the ideal, reference and actual attitudes.

    Parameters
    ----------
    trace : pandas.DataFrame
        With ``time`` [s from the window's start], ``panel_angle_ref`` [rad] and the column the
        ``panel_angle`` role names in ``metadata['roles']`` [rad].
    metadata : Mapping
        With ``window_start`` (ISO 8601) and ``roles``.
    scenario : heliostep.scenario.Scenario
        Its ``site``, ``plant``, ``mirror`` and ``optics`` sections.
    weather : heliostep.solar.irradiance.WeatherFile, optional
        The scenario's weather file already read (:func:`load_weather`); read from the scenario
        when not given.

    Returns
    -------
    pandas.DataFrame
        ``time`` [s], ``dni`` [W/m^2], and for each attitude (``ideal``, ``shared`` for a driven
        secondary, ``reference``, ``actual``: the module's docstring) ``power_<a>_W`` [W],
        ``intercept_<a>``, ``cosine_<a>``, ``end_fraction_<a>`` [-], ``transverse_miss_<a>_m`` and
        ``longitudinal_miss_<a>_m`` [m] (:func:`attitude_light`); with the actual panel, the
        stepping's first-order terms ``driven_error_rad`` [rad], ``cosine_slope_reference``
        [1/rad], ``stepping_first_order_W`` and ``stepping_first_order_cosine_W`` [W] and their slopes in
        the angle [W/rad] (:func:`_first_order_stepping`).
    """
    seconds = trace["time"].to_numpy(dtype=float)
    return pd.DataFrame(
        _light_rows(trace, metadata, scenario, _weather(scenario, weather), float(seconds[0]) if len(seconds) else 0.0)
    )


def _light_rows(
    trace: pd.DataFrame,
    metadata: Mapping,
    scenario,
    weather,
    origin: float,
    window_grid: dict | None = None,
    first_order: bool = True,
    only: Collection[str] | None = None,
    step: float = SUN_GRID_S,
) -> dict:
    """:func:`light_timeseries`'s columns for the rows of ``trace`` (a whole trace or a block of
    one), the sun grid anchored at ``origin`` (the whole trace's first time [s]): the grid
    points are ``origin + k SUN_GRID_S`` whatever the block, so blocks give the rows the whole
    trace gives. ``window_grid``: :func:`sun_grid` at the points k = 0, 1, ... already computed (used
    where it covers the block's points); ``first_order``: with the stepping's first-order columns (where the
    reference's are); ``only``: those attitudes' columns alone (and ``time``, ``dni``; None: every one's);
    ``step``: the grid's [s] (SUN_GRID_S in the docstring above)."""
    conf = scenario.optics
    distance, axis = scenario.mirror.mirror_distance, scenario.mirror.axis
    h = scenario.plant.to_plant().tube_height
    seconds = trace["time"].to_numpy(dtype=float)
    first, last = grid_span(seconds, origin, step)
    if window_grid is not None and last < len(window_grid["time"]):
        points = grid_slice(window_grid, first, last + 1)
    else:
        points = sun_grid(origin + np.arange(first, last + 1) * step, metadata, scenario, weather)
    grid_s = points["time"]
    sun = np.stack([np.interp(seconds, grid_s, c) for c in points["sun"]])
    sun /= np.linalg.norm(sun, axis=0)
    up = np.interp(seconds, grid_s, points["elevation"]) > 0.0
    dni = np.interp(seconds, grid_s, points["dni"])
    attitudes, on_grid, driven = _attitudes(trace, metadata, axis, points, seconds)
    out = {"time": seconds, "dni": dni}
    for name, (primary, secondary) in attitudes.items():
        if only is not None and name not in only:  # the columns of the figures asked for alone
            continue
        image = None
        if name in on_grid:  # a sun-alone attitude: its image from the sun grid
            image = interpolated_image(points, on_grid[name], (seconds, sun, primary, secondary), distance, h, conf)
        light = attitude_light(sun, dni, up, primary, secondary, distance, h, conf, image=image)
        out.update(
            {
                f"power_{name}_W": light["power_W"],
                f"intercept_{name}": light["intercept"],
                f"cosine_{name}": light["cosine"],
                f"end_fraction_{name}": light["end_fraction"],
                f"transverse_miss_{name}_m": light["transverse_miss_m"],
                f"longitudinal_miss_{name}_m": light["longitudinal_miss_m"],
            }
        )
    if driven["actual"] is not None and first_order and "power_reference_W" in out:
        light_of = lambda p, q: attitude_light(sun, dni, up, p, q, distance, h, conf)  # noqa: E731
        out.update(_first_order_stepping(light_of, attitudes["reference"], axis, out, driven))
    return out


def _attitudes(trace: pd.DataFrame, metadata: Mapping, axis: str, points: dict, seconds: np.ndarray):
    """The attitudes (primary, secondary) [rad] at the rows whose light :func:`_light_rows` reports:
    ``ideal``, ``shared`` (the ideal with the primary shared; secondary axis), ``reference`` and
    ``actual`` (the driven angle from the trace, where it has it); and the sun-alone attitudes
    (ideal, shared) at the grid ``points``; the driven angles (``reference``, ``actual`` or None)."""
    grid_s = points["time"]
    ideal_p, ideal_q = (np.interp(seconds, grid_s, points[key]) for key in ("ideal_primary", "ideal_secondary"))
    shared_p = ideal_p - np.interp(seconds, grid_s, points["sharing"])
    panel_column = metadata.get("roles", {}).get("panel_angle")
    driven = {
        "reference": trace["panel_angle_ref"].to_numpy(dtype=float),
        "actual": trace[panel_column].to_numpy(dtype=float) if panel_column in trace else None,
    }
    attitudes = {"ideal": (ideal_p, ideal_q)}
    on_grid = {"ideal": (points["ideal_primary"], points["ideal_secondary"])}
    if axis == "secondary":  # the ideal with the primary shared: what sharing it costs
        attitudes["shared"] = (shared_p, ideal_q)
        on_grid["shared"] = (points["ideal_primary"] - points["sharing"], points["ideal_secondary"])
    for name, angle in driven.items():
        if angle is not None:
            attitudes[name] = (shared_p, angle) if axis == "secondary" else (angle, ideal_q)
    return attitudes, on_grid, driven


def _first_order_stepping(light_of, reference, axis: str, out: dict, driven: dict) -> dict:
    """The stepping's first-order terms at each row, central differences of :data:`COSINE_STEP`
    in the driven angle at the reference attitude: ``driven_error_rad`` (actual - reference)
    [rad], ``cosine_slope_reference`` (d cos / d theta) [1/rad], ``stepping_first_order_W`` =
    (dP_ref / d theta) * error (the cosine, the intercept and the end fraction together) and its
    cosine part ``stepping_first_order_cosine_W`` = P_ref (d cos / d theta) / cos * error [W], and their
    slopes ``power_slope_reference_W_per_rad`` and ``cosine_power_slope_reference_W_per_rad`` [W/rad].
    ``light_of(primary, secondary)``: :func:`attitude_light` of the row's sun and DNI."""
    primary, secondary = reference
    step = np.array(COSINE_STEP)
    turned = []
    for sign in (1.0, -1.0):
        angles = (primary, secondary + sign * step) if axis == "secondary" else (primary + sign * step, secondary)
        turned.append(light_of(*angles))
    slope = (turned[0]["cosine"] - turned[1]["cosine"]) / (2.0 * step)
    power_slope = (turned[0]["power_W"] - turned[1]["power_W"]) / (2.0 * step)
    error = driven["actual"] - driven["reference"]
    cosine = out["cosine_reference"]
    ratio = np.divide(slope, cosine, out=np.zeros_like(slope), where=cosine > 0)
    return {
        "driven_error_rad": error,
        "cosine_slope_reference": slope,
        "power_slope_reference_W_per_rad": power_slope,
        "cosine_power_slope_reference_W_per_rad": out["power_reference_W"] * ratio,
        "stepping_first_order_W": power_slope * error,
        "stepping_first_order_cosine_W": out["power_reference_W"] * ratio * error,
    }


_EVERY = ("ideal", "shared", "reference", "actual", "first_order")

#: What each of :func:`light_figures`' figures takes: the attitudes whose light it integrates (a driven
#: primary has no ``shared``) and ``first_order``, the stepping's first-order terms.
FIGURE_NEEDS: dict[str, tuple[str, ...]] = {
    "light_energy_ideal_J": ("ideal",),
    "light_energy_reference_J": ("reference",),
    "light_lost_shared_primary_J": ("ideal", "shared"),
    "light_lost_reference_law_J": ("ideal", "shared", "reference"),
    "light_lost_stowed_J": ("ideal", "actual"),
    "light_lost_stowed_share": ("ideal", "actual"),
    "light_energy_J": ("actual",),
    **dict.fromkeys(
        ("light_lost_stepping_J", "light_lost_stepping_fraction", "light_stepping_change_J"), ("reference", "actual")
    ),
    **dict.fromkeys(
        ("light_stepping_first_order_J", "light_stepping_first_order_cosine_J", "light_stepping_mean_error_rad"),
        ("reference", "actual", "first_order"),
    ),
    **dict.fromkeys(
        ("light_lost_J", "light_lost_fraction", "mean_intercept", "max_transverse_miss_m", "max_longitudinal_miss_m"),
        ("ideal", "actual"),
    ),
    "dni_source": (),
    "light_notes": _EVERY,  # (:func:`light_notes`: of the figures above)
}


class LightIntegrals:
    """:func:`light_figures` accumulated over a trace's rows taken in blocks, in time order
    (each block a frame with :func:`light_timeseries`'s columns): trapezoids carried across the
    blocks by the previous block's last row, the intercept's weighted sums, the largest misses.
    It holds one block's rows (``max_block_rows``, the largest block) and nothing that grows with
    the trace. ``weather``: see :func:`light_timeseries`. ``first_order=False``: without the
    stepping's first-order terms (their figures None; two attitudes' light fewer at every row).
    ``wanted``: the names of the figures to compute (:data:`FIGURE_NEEDS`; None: all), the light of
    the attitudes they need alone computed at the rows (each figure the same bit for bit as among all).
    ``sun_grid_s``: the step of the sun grid the rows interpolate [s]; rows as sparse as it or sparser
    (a composed case's, :mod:`heliostep.run.step_family`) take a grid at their own spacing, computing the
    sun and the sun-alone attitudes at no more points than the rows."""

    def __init__(
        self,
        metadata: Mapping,
        scenario,
        weather=None,
        first_order: bool = True,
        wanted: Collection[str] | None = None,
        sun_grid_s: float = SUN_GRID_S,
    ):
        self.metadata, self.scenario, self.sun_grid_s = metadata, scenario, sun_grid_s
        self.wanted = None if wanted is None else frozenset(wanted)
        unknown = sorted(set(self.wanted or ()) - set(FIGURE_NEEDS))
        if unknown:
            raise ValueError(f"no light figures {unknown}: the light figures are {sorted(FIGURE_NEEDS)}")
        needs = set(_EVERY) if self.wanted is None else {n for name in self.wanted for n in FIGURE_NEEDS[name]}
        self.first_order = first_order
        self._first_order_rows = first_order and "first_order" in needs
        self._attitudes = needs - {"first_order"}
        self._weather = _weather(scenario, weather)
        self._origin: float | None = None
        self._previous: dict | None = None  # the last row so far: time and power of each attitude
        self._energy: dict[str, float] = {}
        self._max_miss = {"transverse": np.nan, "longitudinal": np.nan}
        self._lit = 0
        self.rows = 0
        self.max_block_rows = 0
        self._window_grid: dict | None = None  # sun_grid over the whole window, from the first row
        self._marks = RowMarks(self.metadata.get("drive", {}).get("step_times", []))  # the rows' side (light_rows)

    def __call__(self, block: pd.DataFrame) -> None:
        if not len(block):
            return
        seconds = block["time"].to_numpy(dtype=float)
        if self._origin is None:
            self._origin = float(seconds[0])
            start, end = self.scenario.window_bounds()
            duration = (end - start).total_seconds()
            self._window_grid = window_sun_grid(
                self._origin, duration, self.metadata, self.scenario, self._weather, self.sun_grid_s
            )
        series = _light_rows(
            block,
            self.metadata,
            self.scenario,
            self._weather,
            self._origin,
            self._window_grid,
            self._first_order_rows,
            self._attitudes,
            self.sun_grid_s,
        )
        powers = {key[len("power_") : -len("_W")]: value for key, value in series.items() if key.startswith("power_")}
        if "stepping_first_order_W" in series:
            powers["first_order"] = series["stepping_first_order_W"]
            powers["first_order_cosine"] = series["stepping_first_order_cosine_W"]
            # the error weighted by the power in time (rows cluster at the steps: a sum over rows is biased)
            powers["error_weighted"] = series["power_reference_W"] * series["driven_error_rad"]
        if "intercept_actual" in series and "power_ideal_W" in series:
            # the actual intercept weighted by the ideal power in time
            powers["intercept_weighted"] = series["power_ideal_W"] * series["intercept_actual"]
        spans = self.metadata.get("drive", {}).get("stowed_spans_s")
        stowed = None
        if spans and "power_actual_W" in series and "power_ideal_W" in series:
            # the light while stowed (off tracking, heliostep.drive.stow)
            stowed = np.zeros(len(seconds), dtype=bool)
            for a, b in spans:
                stowed |= (seconds >= a) & (seconds <= b)
            powers["stowed_ideal"] = np.where(stowed, series["power_ideal_W"], 0.0)
            powers["stowed_actual"] = np.where(stowed, series["power_actual_W"], 0.0)
        if "power_actual_W" in series:
            self._mark_rows(block, seconds, series, stowed)
        for name, power in powers.items():
            time = seconds
            if self._previous is not None:
                time = np.concatenate([[self._previous["time"]], seconds])
                power = np.concatenate([[self._previous[name]], power])
            self._energy[name] = self._energy.get(name, 0.0) + _energy(power, time)
        self._previous = {"time": float(seconds[-1]), **{n: float(p[-1]) for n, p in powers.items()}}
        if "power_actual_W" in series and "power_ideal_W" in series:
            weight = series["power_ideal_W"]
            lit = weight > 0
            self._lit += int(np.count_nonzero(lit))
            for key in self._max_miss:
                miss = np.abs(series[f"{key}_miss_actual_m"][lit])
                if miss.size:
                    self._max_miss[key] = float(np.fmax(self._max_miss[key], np.fmax.reduce(miss)))
        self.rows += len(block)
        self.max_block_rows = max(self.max_block_rows, len(block))

    def _mark_rows(self, block: pd.DataFrame, seconds: np.ndarray, series: dict, stowed: np.ndarray | None) -> None:
        """The rows' integrals, and the powers' slopes at the marks (:class:`.light_rows.RowMarks`)."""
        panel = self.metadata.get("roles", {}).get("panel_angle")
        reference = block["panel_angle_ref"].to_numpy(dtype=float)
        error = block[panel].to_numpy(dtype=float) - reference

        def slopes(marked: np.ndarray) -> dict:
            rows = block.iloc[np.repeat(marked, 3)].copy()  # each row turned by +, 0 and - COSINE_STEP, in order
            rows[panel] = rows[panel].to_numpy(dtype=float) + np.tile([COSINE_STEP, 0.0, -COSINE_STEP], len(marked))
            power = self._light_at(rows, ("actual",))["power_actual_W"]
            up, at, down = power[0::3], power[1::3], power[2::3]
            actual = (up - down) / (2.0 * COSINE_STEP)  # the actual attitude's slope in its angle, its curvature
            out = {"actual": actual, "actual''": (up - 2.0 * at + down) / COSINE_STEP**2}
            if "power_slope_reference_W_per_rad" in series:
                out["first_order"] = series["power_slope_reference_W_per_rad"][marked]
                out["first_order_cosine"] = series["cosine_power_slope_reference_W_per_rad"][marked]
                out["error_weighted"] = series["power_reference_W"][marked]
            if stowed is not None:
                out["stowed_actual"] = np.where(stowed[marked], actual, 0.0)
                out["stowed_actual''"] = np.where(stowed[marked], out["actual''"], 0.0)
            return out

        self._marks(seconds, error, reference, slopes)

    def _light_at(self, rows: pd.DataFrame, attitudes: Collection[str]) -> dict:
        """:func:`_light_rows` of a few rows besides the trace's (turned, the swing's), on the window's sun grid."""
        origin = 0.0 if self._origin is None else self._origin
        grid = self._window_grid
        return _light_rows(rows, self.metadata, self.scenario, self._weather, origin, grid, False, attitudes)

    def _swing_misses(self, solution: Mapping | None) -> dict[str, float]:
        """The actual attitude's largest misses (lit) at the solution's swing (:func:`.light_rows.swing_rows`)."""
        rows = swing_rows(solution, self.metadata.get("roles", {}).get("panel_angle"))
        if rows is None:
            return {}
        series = self._light_at(rows, ("ideal", "actual"))
        lit = series["power_ideal_W"] > 0  # lit as the rows are: by the ideal attitude
        if not lit.any():
            return {}
        return {key: float(np.abs(series[f"{key}_miss_actual_m"][lit]).max()) for key in self._max_miss}

    def figures(self, solution: Mapping | None = None) -> dict:
        """The figures of the rows taken (see :func:`light_figures`), the powers that depend on the driven
        angle corrected between the rows with ``solution``'s error integrals (default: the metadata's
        ``solution_figures``; :mod:`heliostep.results.light.rows`)."""
        solution = solution if solution is not None else self.metadata.get("solution_figures")
        fixes = corrections(self._marks, solution)
        energy = {name: value + fixes.get(name, 0.0) for name, value in self._energy.items()}
        ideal, reference = energy.get("ideal", 0.0), energy.get("reference", 0.0)
        shared = energy.get("shared", ideal)  # a driven primary shares nothing
        figures: dict[str, Any] = {
            "light_energy_ideal_J": ideal,
            "light_energy_reference_J": reference,
            "light_lost_shared_primary_J": ideal - shared,
            "light_lost_reference_law_J": shared - reference,
        }
        if "stowed_ideal" in energy:  # the light lost while stowed, and its share of the ideal
            lost = energy["stowed_ideal"] - energy["stowed_actual"]
            figures["light_lost_stowed_J"] = lost
            figures["light_lost_stowed_share"] = lost / ideal if ideal > 0 else None
        if "actual" in energy:
            actual = energy["actual"]
            figures["light_energy_J"] = actual
            figures["light_lost_stepping_J"] = reference - actual
            figures["light_lost_stepping_fraction"] = (reference - actual) / reference if reference > 0 else 0.0
            figures["light_stepping_change_J"] = actual - reference
            if self.first_order:
                figures["light_stepping_first_order_J"] = energy.get("first_order", 0.0)
                figures["light_stepping_first_order_cosine_J"] = energy.get("first_order_cosine", 0.0)
                weighted = energy.get("error_weighted", 0.0)
                figures["light_stepping_mean_error_rad"] = weighted / reference if reference > 0 else None
            else:  # not computed (a sweep's case)
                figures["light_stepping_first_order_J"] = figures["light_stepping_first_order_cosine_J"] = None
                figures["light_stepping_mean_error_rad"] = None
            figures["light_lost_J"] = ideal - actual
            figures["light_lost_fraction"] = (ideal - actual) / ideal if ideal > 0 else 0.0
            intercepted = energy.get("intercept_weighted", 0.0)
            figures["mean_intercept"] = intercepted / ideal if ideal > 0 else None
            # the rows' largest misses, or larger ones at the swing
            swing = (
                self._swing_misses(solution) if self._wants("max_transverse_miss_m", "max_longitudinal_miss_m") else {}
            )
            for key, value in self._max_miss.items():
                figures[f"max_{key}_miss_m"] = float(np.fmax(value, swing.get(key, np.nan))) if self._lit else None
        figures["dni_source"] = str(self.scenario.optics.weather_file or "clear sky (Ineichen-Perez, pvlib)")
        if self._wants("light_notes"):
            figures["light_notes"] = light_notes(
                figures, self.scenario.mirror.axis, self.scenario.mirror.mirror_distance
            )
        return figures if self.wanted is None else {name: v for name, v in figures.items() if name in self.wanted}

    def _wants(self, *names: str) -> bool:
        return self.wanted is None or not self.wanted.isdisjoint(names)


def _energy(power: np.ndarray, time: np.ndarray) -> float:
    return float(np.sum(0.5 * (power[1:] + power[:-1]) * np.diff(time))) if len(time) > 1 else 0.0


def light_figures(trace: pd.DataFrame, metadata: Mapping, scenario, weather=None) -> dict:
    """A run's light figures: energy on the tube (ideal, reference, actual) and the losses.

    Parameters
    ----------
    trace, metadata, scenario, weather
        See :func:`light_timeseries`.

    Returns
    -------
    dict
        ``light_energy_ideal_J``, ``light_energy_reference_J``, ``light_energy_J`` (actual;
        absent without the panel-angle column) [J]; the parts of ideal - actual (module
        docstring): ``light_lost_shared_primary_J`` (ideal - shared; exactly 0 at d = 0 and for a
        driven primary), ``light_lost_reference_law_J`` (shared - reference) and
        ``light_lost_stepping_J`` (reference - actual, kept for the sweep's table and the CLI),
        ``light_lost_stepping_fraction`` (of the reference); the stepping signed,
        ``light_stepping_change_J`` (actual - reference), its first-order term
        ``light_stepping_first_order_J`` and the cosine's part of it
        ``light_stepping_first_order_cosine_J`` [J], the driven axis' error averaged over the
        window weighted by the reference power, ``light_stepping_mean_error_rad`` [rad];
        ``light_lost_J`` and ``light_lost_fraction`` (ideal - actual, and of the ideal);
        ``mean_intercept`` (actual, weighted by the ideal power in time: a ratio of trapezoids);
        ``max_transverse_miss_m``, ``max_longitudinal_miss_m`` (actual, while the sun is up);
        ``dni_source`` and ``light_notes`` (:func:`light_notes`: the figures' meaning, and which
        are noise). (:class:`LightIntegrals` fed the whole trace as one block.)
    """
    integrals = LightIntegrals(metadata, scenario, weather)
    integrals(trace)
    return integrals.figures()
