"""The sun grid the light at the rows interpolates: the sun, the DNI and the sun-alone angles every
:data:`SUN_GRID_S` from the trace's first row, the whole window's kept for the runs that share it.

Details: docs/light.md, ``heliostep.results.light.on_tube``.
"""

from __future__ import annotations

from collections import OrderedDict
from collections.abc import Mapping
from pathlib import Path

import numpy as np
import pandas as pd

from heliostep.solar import irradiance
from heliostep.solar.field import sharing_errors
from heliostep.solar.sun import solar_position, sun_vector
from heliostep.solar.tracking import two_axis_angles

__all__ = ["KEPT_GRIDS", "SUN_GRID_S", "grid_slice", "grid_span", "sun_grid", "window_sun_grid"]

#: Sampling step of the sun's position and the DNI before interpolation onto the rows [s].
SUN_GRID_S = 10.0

#: Whole windows' grids kept (:func:`window_sun_grid`), the least recently used dropped beyond.
KEPT_GRIDS = 16

_kept: OrderedDict[tuple, tuple[object, dict]] = OrderedDict()  # key -> (the weather it was made with, grid)


def _row_times(seconds: np.ndarray, metadata: Mapping) -> pd.DatetimeIndex:
    start = pd.Timestamp(metadata["window_start"])
    start = start if start.tzinfo is not None else start.tz_localize(metadata.get("timezone", "UTC"))
    return start + pd.to_timedelta(seconds, unit="s")


def grid_span(seconds: np.ndarray, origin: float, step: float = SUN_GRID_S) -> tuple[int, int]:
    """The first and last index k of the grid points ``origin + k step`` that bracket ``seconds``."""
    first = max(int(np.floor((seconds[0] - origin) / step)), 0)
    last = int(np.ceil((seconds[-1] - origin) / step))
    if origin + last * step < seconds[-1]:
        last += 1
    return first, max(last, first + 1)


def sun_grid(grid_s: np.ndarray, metadata: Mapping, scenario, weather) -> dict:
    """What the light at the rows interpolates, at the grid times ``grid_s`` [s from the window's
    start]: ``time`` [s], ``elevation`` [deg], ``sun`` (3, n) [-] (plant frame), ``dni``
    [W/m^2], the ideal two-axis angles ``ideal_primary`` and ``ideal_secondary`` and the shared
    primary's ``sharing`` error (0 while the sun is down, and everywhere for the central mirror,
    d = 0) [rad]. Every value is a function of its grid time alone (and of what :func:`_grid_key` names)."""
    site, plant = scenario.site.to_site(), scenario.plant.to_plant()
    distance, h = scenario.mirror.mirror_distance, plant.tube_height
    grid = _row_times(grid_s, metadata)
    position = solar_position(grid, site.latitude, site.longitude, site.altitude)
    elevation, azimuth = position["apparent_elevation"].to_numpy(), position["azimuth"].to_numpy()
    ideal_primary, ideal_secondary = two_axis_angles(elevation, azimuth, distance, h, plant.azimuth)
    # the shared primary: the central mirror's law plus a mounting offset exact at solar noon; the
    # central mirror's (d = 0) own primary is the shared one: its error is 0 by definition
    if distance == 0.0:
        sharing = np.zeros(len(grid_s))
    else:
        sharing = sharing_errors(grid, site, plant, scenario.window.date, [distance], sun=position)[:, 0]
    return {
        "time": grid_s,
        "elevation": elevation,
        "sun": np.stack(sun_vector(elevation, azimuth, plant.azimuth)),
        "dni": irradiance.dni(grid, site, weather, sun=position).to_numpy() * _clouds(scenario, grid_s),
        "ideal_primary": np.asarray(ideal_primary),
        "ideal_secondary": np.asarray(ideal_secondary),
        "sharing": np.nan_to_num(sharing),
    }


def _clouds(scenario, seconds: np.ndarray) -> np.ndarray:
    """The share of the DNI the scenario's clouds (``tracking.clouds``) leave at ``seconds``."""
    tracking = getattr(scenario, "tracking", None)
    return irradiance.cloud_fraction(seconds, tracking.cloud_spans if tracking is not None else [])


def grid_slice(grid: dict, start: int, stop: int) -> dict:
    """The grid's points ``start`` to ``stop`` (views)."""
    return {key: value[..., start:stop] for key, value in grid.items()}


def window_sun_grid(
    origin: float, duration: float, metadata: Mapping, scenario, weather, step: float = SUN_GRID_S
) -> dict | None:
    """:func:`sun_grid` at every grid point, ``step`` [s] apart, from the first row, at ``origin`` [s], to the
    window's end, ``duration`` [s] (per block it would pay pvlib's fixed overheads each time); None when the
    first row is at or past the window's end. The last :data:`KEPT_GRIDS` are kept, read-only, by everything
    their values depend on (:func:`_grid_key`): a sweep's cases of one day and mirror share one."""
    if not duration > origin:
        return None
    _, last = grid_span(np.array([duration]), origin, step)
    grid_s = origin + np.arange(last + 1) * step
    key = _grid_key(origin, step, len(grid_s), metadata, scenario, weather)
    found = None if key is None else _kept.get(key)
    if found is not None and found[0] is weather:
        _kept.move_to_end(key)  # type: ignore[arg-type]
        return found[1]
    grid = sun_grid(grid_s, metadata, scenario, weather)
    if key is not None:
        for values in grid.values():
            values.flags.writeable = False  # shared by the runs that find it
        _kept[key] = (weather, grid)
        while len(_kept) > KEPT_GRIDS:
            _kept.popitem(last=False)
    return grid


def _grid_key(origin: float, step: float, points: int, metadata: Mapping, scenario, weather) -> tuple | None:
    """What :func:`sun_grid`'s values at ``points`` points ``step`` apart from ``origin`` depend on besides pvlib: the
    window's start, the site, the plant, the mirror's distance, the date, the clouds and the weather (a
    file already read: that very object). None: not to be kept (a weather file's path, read anew each
    time as it may have changed; a scenario whose sections cannot be keys)."""
    if isinstance(weather, str | Path):
        return None
    source = None if weather is None else id(weather)  # (the entry holds it: its id is not reused while kept)
    tracking = getattr(scenario, "tracking", None)
    clouds = tuple(tracking.cloud_spans) if tracking is not None else ()
    start = (str(metadata["window_start"]), str(metadata.get("timezone", "UTC")))
    sections = (scenario.site, scenario.plant, scenario.mirror.mirror_distance, scenario.window.date)
    key = (float(origin), float(step), points, start, *sections, clouds, source)
    try:
        hash(key)
    except TypeError:
        return None
    return key
