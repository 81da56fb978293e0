"""What a sizing was sized for: the sheet's ``inputs`` block (site, window and days, mirror and
transmission, wind, safety factor, every ``--set``, the files' digests and the versions), so that a sheet
read away from its command still says which site, load and software it holds for.
"""

from __future__ import annotations

import hashlib
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from heliostep.drive.wind import air_density, moment_coefficient
from heliostep.errors import InputError
from heliostep.input_files import MAX_YAML_BYTES, read_input_bytes
from heliostep.run import run_versions
from heliostep.scenario import Scenario

__all__ = ["WIND_SOURCE_KEYS", "check_wind_given", "file_digest", "sizing_inputs"]

#: The scenario's keys that give a sizing its wind (without ``--design-gust``).
WIND_SOURCE_KEYS = ("wind.speed", "wind.weather_file", "wind.profile", "wind.moment")

#: The wind load's model in words (:mod:`heliostep.drive.wind`).
WIND_MODEL = (
    "flat plate: Hoerner's normal force C_N = 1 / (0.222 + 0.283 / sin a), Joessel's centre of pressure "
    "x_cp / c = 0.195 + 0.305 sin a; M = C_M 1/2 rho (G v)^2 A c about the mid-chord"
)


def check_wind_given(source: str, raw: dict, design_gust: float | None) -> None:
    """Refuse a sizing with no wind: no ``--design-gust`` and none of :data:`WIND_SOURCE_KEYS` in the
    scenario (``raw``, its overrides applied). Its default 0 N.m would pass a motor that holds no wind."""
    wind = raw.get("wind")
    given = isinstance(wind, dict) and any(key.partition(".")[2] in wind for key in WIND_SOURCE_KEYS)
    if design_gust is None and not given:
        raise InputError(
            f"{source}: no wind to size against: expected --design-gust M_PER_S or a wind source in the "
            f"scenario ({', '.join(WIND_SOURCE_KEYS)}; --set KEY=VALUE gives one); without one every "
            "candidate would be judged against 0 N.m of wind"
        )


def file_digest(path: str | Path, what: str) -> str:
    """The sha256 of the file ``path`` as read now (hex), an :class:`InputError` naming it if unreadable."""
    return hashlib.sha256(read_input_bytes(path, what, MAX_YAML_BYTES)).hexdigest()


def sizing_inputs(
    scenario: Scenario,
    *,
    scenario_digest: str,
    catalogue: str,
    catalogue_digest: str,
    overrides: Sequence[str],
    design_gust: float | None,
    wind_moment: float | None,
    wind_source: str,
    safety_factor: float,
    days: dict,
) -> dict:
    """The sheet's ``inputs`` block: everything the verdict holds for, as the sizing resolved it; ``days``:
    the days sized and why (:meth:`heliostep.sizing.days.DaySelection.record`)."""
    return {
        "scenario": {"name": scenario.name, "file": scenario.source, "sha256": scenario_digest},
        "catalogue": {"file": catalogue, "sha256": catalogue_digest},
        "overrides": list(overrides),
        "site": scenario.site.model_dump(mode="json"),
        "window": scenario.window.model_dump(mode="json", exclude_none=True),
        "days": days,
        "mirror": _mirror(scenario),
        "transmission": scenario.transmission.model_dump(mode="json"),
        "sequencer": scenario.sequencer.model_dump(
            mode="json", include={"mode", "microsteps", "idle_current_fraction"}
        ),
        "wind": _wind(scenario, design_gust, wind_moment, wind_source),
        "safety_factor": safety_factor,
        "versions": run_versions(),
    }


def _mirror(scenario: Scenario) -> dict:
    """The driven mirror: where it is, its axis and its size (the wind's area and chord)."""
    mirror, optics = scenario.mirror, scenario.optics
    return {
        "distance_m": mirror.mirror_distance,
        "index": mirror.index,
        "axis": mirror.axis,
        "width_m": optics.mirror_width,
        "length_m": optics.mirror_length,
        "aperture_area_m2": optics.aperture_area,
    }


def _wind(scenario: Scenario, design_gust: float | None, wind_moment: float | None, source: str) -> dict:
    """The wind the candidates are judged against: its source, the scenario's wind keys, the design gust,
    the load model and its coefficients (the peak moment coefficient, gust factor, air density)."""
    wind = scenario.wind
    attack = np.radians(np.linspace(0.0, 90.0, 9001))
    coefficients = moment_coefficient(attack)
    peak = int(np.argmax(coefficients))
    return {
        "source": source,
        "design_gust_m_s": design_gust,
        "design_moment_Nm": wind_moment,
        "moment_Nm": wind.moment if design_gust is None and not wind.has_speed else None,  # when it is the load
        "speed_m_s": wind.speed,
        "weather_file": wind.weather_file,
        "profile": None if wind.profile is None else [list(point) for point in wind.profile],
        "direction_deg": wind.direction,
        "stow_speed_m_s": wind.stow_speed,
        "model": WIND_MODEL,
        "peak_moment_coefficient": float(coefficients[peak]),
        "peak_at_attack_deg": float(np.degrees(attack[peak])),
        "gust_factor": wind.gust_factor,  # on a wind speed and the stow wind; a design gust is a peak speed
        "air_temperature_C": wind.air_temperature,
        "air_density_kg_m3": float(air_density(scenario.site.altitude, wind.air_temperature)),
    }
