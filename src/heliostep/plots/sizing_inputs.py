"""The sizing sheet's first two sections (:mod:`heliostep.plots.sizing`): the verdict paragraph, and what the
sheet was sized for (its ``inputs``: site, window and days, mirror and transmission, wind, safety factor,
every ``--set``, the files' digests, the versions), so that a printed sheet names its site and load.
"""

from __future__ import annotations

import html
from collections.abc import Mapping, Sequence
from typing import Any

__all__ = ["PRINT_STYLE", "inputs_section", "sheet_title", "verdict_paragraph"]

#: Printed from a browser, each section starts a page (the first on the first).
PRINT_STYLE = (
    "@media print{body{margin:0;max-width:none}section{break-before:page}section:first-of-type{break-before:auto}}"
)

#: The inputs table's rows: (what, with its unit in brackets; the path into ``inputs``).
INPUT_ROWS: tuple[tuple[str, str], ...] = (
    ("scenario [name]", "scenario.name"),
    ("scenario file [path]", "scenario.file"),
    ("scenario file sha256 [hex]", "scenario.sha256"),
    ("site latitude [deg N]", "site.latitude"),
    ("site longitude [deg E]", "site.longitude"),
    ("site altitude [m]", "site.altitude"),
    ("site time zone [IANA]", "site.timezone"),
    ("window date [YYYY-MM-DD] (its year's days are sized)", "window.date"),
    ("window start [local time]", "window.start"),
    ("window end [local time]", "window.end"),
    ("window duration [s]", "window.duration"),
    ("days sized [day of year]", "days.days"),
    ("why these days [text]", "days.criterion"),
    ("mirror distance from the tube [m]", "mirror.distance_m"),
    ("mirror index in the field [0..12]", "mirror.index"),
    ("driven axis [name]", "mirror.axis"),
    ("mirror width across the axis [m]", "mirror.width_m"),
    ("mirror length [m]", "mirror.length_m"),
    ("mirror aperture [m2]", "mirror.aperture_area_m2"),
    ("pinion radius [m]", "transmission.pinion_radius"),
    ("lever arm [m]", "transmission.lever_arm"),
    ("sequencer mode [name]", "sequencer.mode"),
    ("microsteps [per full step]", "sequencer.microsteps"),
    ("idle current fraction [1]", "sequencer.idle_current_fraction"),
    ("wind source [text]", "wind.source"),
    ("design gust [m/s]", "wind.design_gust_m_s"),
    ("design moment on the panel axis [N.m]", "wind.design_moment_Nm"),
    ("wind.moment [N.m]", "wind.moment_Nm"),
    ("wind.speed [m/s]", "wind.speed_m_s"),
    ("wind.weather_file [path]", "wind.weather_file"),
    ("wind.profile [[s, m/s], ...]", "wind.profile"),
    ("wind direction [deg from N]", "wind.direction_deg"),
    ("stow wind speed [m/s]", "wind.stow_speed_m_s"),
    ("wind load model [text]", "wind.model"),
    ("peak moment coefficient C_M [1]", "wind.peak_moment_coefficient"),
    ("C_M's peak at the angle of attack [deg]", "wind.peak_at_attack_deg"),
    ("gust factor on a wind speed and the stow wind [1]", "wind.gust_factor"),
    ("air temperature [degC] (none: the ISA's)", "wind.air_temperature_C"),
    ("air density [kg/m3]", "wind.air_density_kg_m3"),
    ("safety factor on the load [1]", "safety_factor"),
    ("catalogue file [path]", "catalogue.file"),
    ("catalogue file sha256 [hex]", "catalogue.sha256"),
    ("heliostep [version]", "versions.heliostep"),
    ("Python [version]", "versions.python"),
)


def _at(record: Mapping[str, Any], path: str) -> Any:
    value: Any = record
    for key in path.split("."):
        value = value.get(key) if isinstance(value, Mapping) else None
    return value


def _text(value: Any) -> str:
    if value is None:
        return "–"
    if isinstance(value, float):
        return f"{value:.6g}"
    if isinstance(value, list | tuple):
        return ", ".join(map(_text, value))
    if isinstance(value, Mapping) and "day_of_year" in value:  # a day sized: its number (its reasons below)
        return str(value["day_of_year"])
    return str(value)


def _rows(rows: Sequence[tuple[str, Any]]) -> str:
    body = "".join(f"<tr><td>{html.escape(what)}</td><td>{html.escape(_text(value))}</td></tr>" for what, value in rows)
    head = "<thead><tr><th>input [unit]</th><th>value [in that unit]</th></tr></thead>"
    return f"<table>{head}<tbody>{body}</tbody></table>"


def sheet_title(sheet: Mapping[str, Any]) -> str:
    """The sheet's title: the scenario, its site and how many ``--set`` changed it (escaped)."""
    inputs = sheet.get("inputs") or {}
    site, overrides = inputs.get("site") or {}, inputs.get("overrides") or []
    where = ""
    if site:
        north, east = site["latitude"], site["longitude"]
        where = (
            f" at {abs(north):g}° {'N' if north >= 0 else 'S'}, {abs(east):g}° {'E' if east >= 0 else 'W'}, "
            f"{site['altitude']:g} m ({site['timezone']})"
        )
    changed = f", with {len(overrides)} --set" if overrides else ""
    return html.escape(f"Sizing sheet: {sheet['scenario']}{where}{changed}")


def verdict_paragraph(sheet: Mapping[str, Any]) -> str:
    """The verdict in one paragraph (the chosen drive, its governing case and margin, the next smaller)."""
    text = (sheet.get("verdict") or {}).get("text") or "No candidate was judged."
    return f"<p class='verdict'>{html.escape(text)}</p>"


def inputs_section(sheet: Mapping[str, Any]) -> str:
    """What the sheet was sized for: every input with its unit, each ``--set``, each day's reasons."""
    inputs = sheet.get("inputs") or {}
    overrides = inputs.get("overrides") or []
    rows = [(what, _at(inputs, path)) for what, path in INPUT_ROWS]
    rows[3:3] = [("--set [KEY=VALUE]", item) for item in overrides] or [("--set [KEY=VALUE]", "none")]
    packages = ((inputs.get("versions") or {}).get("packages") or {}).items()
    rows += [(f"{name} [version]", version) for name, version in packages]
    days = "".join(
        f"<li>day {day['day_of_year']} ({html.escape(day['date'])}): {html.escape('; '.join(day['reasons']))}</li>"
        for day in (inputs.get("days") or {}).get("days", [])
    )
    return (
        "<h2>What it was sized for</h2><p>The scenario as sized (its file, then every --set over it), the wind "
        "the candidates are judged against, the files' digests as read and the software's versions.</p>"
        + _rows(rows)
        + (f"<p>The days sized and why:</p><ul>{days}</ul>" if days else "")
    )
