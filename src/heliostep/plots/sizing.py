"""The sizing sheet (``heliostep size``) as one self-contained HTML page: tables with units, plots
embedded as base64 PNG, readable offline (no script, no external file).

:func:`sizing_html` takes the sheet (:func:`heliostep.sizing.verdict.judge`'s mapping, with the
run's header keys) and returns the page. Figures are :class:`matplotlib.figure.Figure` (no pyplot).
"""

from __future__ import annotations

import base64
import html
import io
import math
from collections.abc import Mapping, Sequence
from typing import Any

from matplotlib.figure import Figure

from heliostep.plots.png import save_png
from heliostep.plots.sizing_inputs import PRINT_STYLE, inputs_section, sheet_title, verdict_paragraph

__all__ = ["margins_png", "sizing_html", "speed_torque_png"]

_DPI = 110


def _png(figure: Figure) -> bytes:
    buffer = io.BytesIO()
    save_png(figure, buffer, _DPI, bbox_inches="tight")
    return buffer.getvalue()


def speed_torque_png(sheet: Mapping[str, Any]) -> bytes | None:
    """Each candidate's pull-out torque against step rate, its holding torque, and the load x the safety
    factor (the worst candidate's budget); None without curves."""
    curves = [(c["name"], c["speed_torque"]) for c in sheet["candidates"] if "speed_torque" in c]
    if not curves:
        return None
    figure = Figure(figsize=(7.5, 4.5))
    axes = figure.add_subplot()
    worst = {c["name"]: c["speed_torque_worst"] for c in sheet["candidates"] if "speed_torque_worst" in c}
    for name, curve in curves:
        (line,) = axes.plot(curve["step_rates_per_s"], curve["pull_out_torques_Nm"], "o-", label=f"{name}, pull-out")
        axes.axhline(curve["holding_torque_Nm"], color=line.get_color(), linestyle=":", linewidth=1)
        if name in worst:
            axes.plot(
                worst[name]["step_rates_per_s"],
                worst[name]["pull_out_torques_Nm"],
                "x--",
                color=line.get_color(),
                label=f"{name}, pull-out at the ranges' worst corner",
            )
    loads = [row["load_budget"]["total_Nm"] for c in sheet["candidates"] for row in c["currents"]]
    if loads:
        axes.axhline(
            max(loads) * sheet["safety_factor"],
            color="black",
            linestyle="--",
            label=f"load x {sheet['safety_factor']:g} (worst instant)",
        )
    axes.set_xlabel("step rate [full steps/s]")
    axes.set_ylabel("torque on the motor shaft [N.m]")
    axes.set_title("speed-torque curves at each candidate's largest current (dotted: holding torque)")
    axes.grid(True, alpha=0.3)
    axes.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.02, 1.0), borderaxespad=0.0)  # beside the data
    return _png(figure)


def margins_png(sheet: Mapping[str, Any]) -> bytes | None:
    """The tracking and idle margins of every candidate and current, against the safety factor."""
    rows = [(f"{c['name']}\n{row['current_A']:g} A", row) for c in sheet["candidates"] for row in c["currents"]]
    if not rows:
        return None
    figure = Figure(figsize=(max(6.0, 0.7 * len(rows) + 2), 4.5))
    axes = figure.add_subplot()
    positions = range(len(rows))
    cap = 10.0 * sheet["safety_factor"]
    bars = (("tracking_margin", "tracking"), ("idle_margin", "idle current"), ("stow_margin", "stowing"))
    for k, (key, label) in enumerate(bars):
        values = [min(float(row[key]), cap) if row.get(key) is not None else 0.0 for _, row in rows]
        axes.bar([p + 0.27 * (k - 1) for p in positions], values, width=0.27, label=label)
    axes.axhline(
        sheet["safety_factor"], color="black", linestyle="--", label=f"safety factor {sheet['safety_factor']:g}"
    )
    axes.set_xticks(list(positions), [name for name, _ in rows], fontsize=7, rotation=90)
    axes.set_ylabel(f"margin to slip [1] (capped at {cap:g})")
    axes.set_title("margins: torque the motor has / load it must carry")
    axes.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.02, 1.0), borderaxespad=0.0)  # beside the data
    return _png(figure)


def number_text(value: float) -> str:
    """A table's number: 4 significant digits, with an exponent only below 1e-3 (``1.298e-11``), never above
    (``119600``, not ``1.196e+05``)."""
    if math.isinf(value):
        return "∞"
    if not math.isfinite(value) or value == 0 or abs(value) < 1e4:
        return f"{value:.4g}"
    return f"{round(value, 3 - math.floor(math.log10(abs(value)))):.0f}"


def kilo_text(value: float | None) -> str | None:
    """An energy [J] in kJ with one decimal (``119.6``), for a column headed [kJ]; None stays None."""
    return None if value is None else f"{value / 1e3:.1f}"


def _cell(value: Any) -> str:
    if value is None:
        return "–"
    if isinstance(value, float):
        return number_text(value)
    if isinstance(value, list | tuple):
        return ", ".join(map(_cell, value))
    return html.escape(str(value))


def _table(headers: Sequence[str], rows: Sequence[Sequence[Any]]) -> str:
    head = "".join(f"<th>{html.escape(h)}</th>" for h in headers)
    body = "".join("<tr>" + "".join(f"<td>{_cell(v)}</td>" for v in row) + "</tr>" for row in rows)
    return f"<table><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>"


def _keyed_table(columns: Sequence[tuple[str, str]], records: Sequence[Mapping[str, Any]]) -> str:
    """A table of ``records``, one row each: ``columns`` are (header with its unit in brackets, the
    record's key); a header without a unit is refused (every table of the sheet carries its units)."""
    unitless = [header for header, _ in columns if not (header.endswith("]") and "[" in header)]
    if unitless:
        raise ValueError(f"table headers without a unit in brackets: {unitless}")
    return _table([header for header, _ in columns], [[record.get(key) for _, key in columns] for record in records])


def _verdict_table(sheet: Mapping[str, Any]) -> str:
    headers = (
        "candidate [name]",
        "current [A]",
        "holding torque [N.m]",
        "step limit from rest [N.m]",
        "load at the worst instant [N.m]",
        "tracking margin [1]",
        "idle margin [1]",
        "stow margin [1]",
        "steps lost [steps]",
        "steps missed [steps]",
        "worst tracking error [deg]",
        "drive energy per day [kJ]",
        "drive energy per year [kWh]",
        "light change vs ideal tracking, stowed included [%]",
        "light lost while stowed [kJ]",
        "governing case [tracking/idle/stow]",
        "verdict [pass/fail]",
        "reasons [text]",
    )
    rows = []
    for c in sheet["candidates"]:
        for row in c["currents"]:
            simulated = row["simulation"]
            rows.append(
                (
                    c["name"],
                    row["current_A"],
                    row["holding_torque_Nm"],
                    row["static_step_limit_Nm"],
                    row["load_budget"]["total_Nm"],
                    row["tracking_margin"],
                    row["idle_margin"],
                    row.get("stow_margin"),
                    simulated["steps_lost"],
                    simulated["missed_steps"],
                    simulated["max_tracking_error_deg"],
                    kilo_text(simulated["drive_energy_per_day_J"]),
                    simulated.get("drive_energy_per_year_kWh"),
                    None if simulated.get("light_change_share") is None else 100.0 * simulated["light_change_share"],
                    kilo_text(simulated.get("light_lost_stowed_J")),
                    (row.get("governing") or {}).get("case"),
                    row["verdict"],
                    "; ".join(row["reasons"]) or "passes",
                )
            )
    return _table(headers, rows)


def _budget_table(sheet: Mapping[str, Any]) -> str:
    records = [{"candidate": c["name"], **c["currents"][0]["load_budget"]} for c in sheet["candidates"]]
    columns = (
        ("candidate [name]", "candidate"),
        ("day [day of year]", "day_of_year"),
        ("time in the window [s]", "time_s"),
        ("panel angle [deg]", "panel_angle_deg"),
        ("ratio g [1]", "ratio"),
        ("wind moment on the panel [N.m]", "wind_moment_Nm"),
        ("wind on the shaft [N.m]", "wind_Nm"),
        ("friction [N.m]", "friction_Nm"),
        ("inertia [N.m]", "inertia_Nm"),
        ("total [N.m]", "total_Nm"),
    )
    return _keyed_table(columns, records)


_STOW_NOTE = (
    "<h2>Load while stowing</h2><p>A stow or return move at the slew rate in a wind at the stow speed (gust "
    "factor on it), at the angle of the least margin; deliverable: the pull-out torque at the move's step rate "
    "(the nominal curve, linear between its rates, scaled to the current by the holding torque), at most the "
    "step limit from rest.</p>"
)


def _stow_table(sheet: Mapping[str, Any]) -> str:
    records = [
        {"candidate": c["name"], "current_A": row["current_A"], "stow_margin": row["stow_margin"], **row["stow_load"]}
        for c in sheet["candidates"]
        for row in c["currents"]
        if row.get("stow_load")
    ]
    columns = (
        ("candidate [name]", "candidate"),
        ("current [A]", "current_A"),
        ("stow wind speed [m/s]", "stow_speed_m_s"),
        ("slew rate [deg/s]", "slew_rate_deg_s"),
        ("angles travelled [deg]", "angles_travelled_deg"),
        ("worst panel angle [deg]", "panel_angle_deg"),
        ("step rate [full steps/s]", "step_rate_per_s"),
        ("wind on the shaft [N.m]", "wind_Nm"),
        ("friction [N.m]", "friction_Nm"),
        ("inertia [N.m]", "inertia_Nm"),
        ("total [N.m]", "total_Nm"),
        ("pull-out at the rate [N.m]", "pull_out_Nm"),
        ("deliverable [N.m]", "deliverable_Nm"),
        ("stow margin [1]", "stow_margin"),
    )
    return _STOW_NOTE + _keyed_table(columns, records)


def _days_table(sheet: Mapping[str, Any]) -> str:
    selection = sheet.get("day_selection") or {"days": [{"day_of_year": d} for d in sheet["days"]]}
    records = [{**day, "why": "; ".join(day.get("reasons", []))} for day in selection["days"]]
    columns = (
        ("day [day of year]", "day_of_year"),
        ("date [YYYY-MM-DD]", "date"),
        ("largest panel rate in the window [deg/s]", "panel_rate_deg_s"),
        ("largest mean wind in the window [m/s]", "wind_speed_m_s"),
        ("why [text]", "why"),
    )
    return _keyed_table(columns, records)


def _catalogue_table(sheet: Mapping[str, Any]) -> str:
    records = [{**c, "inductance_mH": 1e3 * c["inductance_H"]} for c in sheet["candidates"]]
    columns = (
        ("candidate [name]", "name"),
        ("manufacturer [text]", "manufacturer"),
        ("datasheet [text]", "datasheet"),
        ("holding torque, 2 phases on [N.m]", "holding_torque_Nm"),
        ("rated current [A]", "rated_current_A"),
        ("resistance [Ohm]", "resistance_Ohm"),
        ("inductance [mH]", "inductance_mH"),
        ("rotor inertia [kg.m2]", "rotor_inertia_kgm2"),
        ("detent torque [N.m]", "detent_torque_Nm"),
        ("bus [V]", "bus_voltage_V"),
        ("k_e [N.m/A]", "torque_constant_NmA"),
    )
    return _keyed_table(columns, records)


def _curve_table(sheet: Mapping[str, Any]) -> str:
    records = []
    for c in sheet["candidates"]:
        if "speed_torque" not in c:
            continue
        curve, worst = c["speed_torque"], c.get("speed_torque_worst")
        at_worst = dict(zip(worst["step_rates_per_s"], worst["pull_out_torques_Nm"])) if worst else {}
        for rate, torque in zip(curve["step_rates_per_s"], curve["pull_out_torques_Nm"]):
            records.append(
                {
                    "name": c["name"],
                    "current": curve["current_A"],
                    "rate": rate,
                    "torque": torque,
                    "worst": at_worst.get(rate),
                }
            )
    columns = (
        ("candidate [name]", "name"),
        ("current [A]", "current"),
        ("step rate [full steps/s]", "rate"),
        ("pull-out torque [N.m]", "torque"),
        ("pull-out at the ranges' worst corner [N.m]", "worst"),
    )
    return _keyed_table(columns, records)


def _worst_corner_cells(band: Mapping[str, Any]) -> dict[str, Any]:
    """The band table's cells of the days at the worst corner; none where a day there was not simulated
    (its sums would read as a clean 0)."""
    worst = band.get("simulation_worst_corner") or {}
    keys = ("missed_steps", "steps_lost", "max_tracking_error_deg")
    return {f"worst_{key}": None if worst.get("days_unfinished") else worst.get(key) for key in keys if key in worst}


def _band_table(sheet: Mapping[str, Any]) -> str:
    records = [
        {
            **row["band"],
            "name": c["name"],
            "current_A": row["current_A"],
            "tracking_margin": row["tracking_margin"],
            "corner": ", ".join(
                f"{k.rsplit('.', 1)[-1]}={v:g}" for k, v in row["band"]["least_tracking_corner"].items()
            ),
            **_worst_corner_cells(row["band"]),
        }
        for c in sheet["candidates"]
        for row in c["currents"]
        if "band" in row
    ]
    columns = (
        ("candidate [name]", "name"),
        ("current [A]", "current_A"),
        ("corners [count]", "corners"),
        ("tracking margin, nominal [1]", "tracking_margin"),
        ("tracking margin, least over the corners [1]", "tracking_margin_min"),
        ("tracking margin, largest [1]", "tracking_margin_max"),
        ("idle margin, least [1]", "idle_margin_min"),
        ("idle margin, largest [1]", "idle_margin_max"),
        ("stow margin at the worst corner [1]", "stow_margin_worst_corner"),
        ("days at the worst corner: steps lost [steps]", "worst_steps_lost"),
        ("days at the worst corner: steps missed [steps]", "worst_missed_steps"),
        ("days at the worst corner: worst tracking error [deg]", "worst_max_tracking_error_deg"),
        ("corner of the least tracking margin [key=value]", "corner"),
        ("keys not in the margins [key]", "keys_not_in_the_margins"),
    )
    return _keyed_table(columns, records)


def _energy_note(sheet: Mapping[str, Any]) -> str:
    rows = [row["simulation"] for c in sheet["candidates"] for row in c["currents"]]
    estimator = next(
        (r.get("drive_energy_per_year_estimator") for r in rows if r.get("drive_energy_per_year_estimator")), ""
    )
    return (
        f"<p>Drive energy per year: {html.escape(estimator)}. Light change: the light on the receiver over the "
        "simulated windows against ideal two-axis tracking of the same windows, the light lost while stowed "
        "included.</p>"
    )


_STYLE = (
    "body{font-family:sans-serif;margin:2em;max-width:90em}table{border-collapse:collapse;margin:1em 0}"
    "th,td{border:1px solid #999;padding:0.25em 0.5em;font-size:0.85em;vertical-align:top;overflow-wrap:anywhere}"
    "th{background:#eee}img{max-width:100%;height:auto}"
)


def _image(png: bytes | None, alt: str) -> str:
    if png is None:
        return ""
    return f'<p><img alt="{html.escape(alt)}" src="data:image/png;base64,{base64.b64encode(png).decode("ascii")}"></p>'


def _wind_text(wind: Mapping[str, Any]) -> str:
    if wind["moment_Nm"] is None:
        return f"{html.escape(wind['source'])} (each day's moment at its worst instant: the load budget table)"
    return f"{wind['moment_Nm']:.4g} N.m on the panel axis ({html.escape(wind['source'])})"


def _beside_the_verdict(sheet: Mapping[str, Any]) -> str:
    """The band's days' warnings (steps lost or missed, a failed day at the worst corner): not in the verdict,
    listed next to it; empty without any."""
    items = "".join(
        f"<li>{html.escape(c['name'])} at {row['current_A']:g} A: {html.escape(warning)}</li>"
        for c in sheet.get("candidates", [])
        for row in c.get("currents", [])
        for warning in ((row.get("band") or {}).get("simulation_worst_corner") or {}).get("warnings", [])
    )
    return f"<p>Beside the verdict (the uncertainty band):</p><ul>{items}</ul>" if items else ""


def _summary_section(sheet: Mapping[str, Any]) -> list[str]:
    """The first page: the title (scenario and site), the verdict paragraph, the smallest passing drive,
    what the band puts beside it and why each smaller one fails."""
    best = sheet.get("smallest_passing")
    verdict = (
        f"The smallest passing drive: <b>{html.escape(best['candidate'])} at {best['current_A']:g} A</b>."
        if best
        else "<b>No candidate passes.</b>"
    )
    smaller = "".join(
        f"<li>{html.escape(item['candidate'])} at {item['current_A']:g} A ({html.escape(item['verdict'])}): "
        f"{html.escape('; '.join(item['reasons']) or '–')}</li>"
        for item in sheet.get("smaller_ones_fail_because", [])
    )
    status = (
        ""
        if sheet.get("complete", True)
        else (
            "<p><b>Incomplete</b>: interrupted; cases not run: "
            f"{html.escape(', '.join(sheet.get('unfinished_cases', [])))}</p>"
        )
    )
    return [
        f"<h1>{sheet_title(sheet)}</h1>",
        verdict_paragraph(sheet),
        status,
        f"<p>{verdict} Wind: {_wind_text(sheet['wind'])}; "
        f"safety factor {sheet['safety_factor']:g} on the load; days simulated (day of year): "
        f"{html.escape(', '.join(map(str, sheet['days'])))}.</p>",
        _beside_the_verdict(sheet),
        f"<h2>Why each smaller one fails</h2><ul>{smaller or '<li>none smaller</li>'}</ul>",
    ]


def _sections(sheet: Mapping[str, Any]) -> list[list[str]]:
    """The sheet's sections in order, each printed on a page of its own."""
    return [
        _summary_section(sheet),
        [inputs_section(sheet)],
        ["<h2>Verdicts</h2>", _verdict_table(sheet), _energy_note(sheet), _image(margins_png(sheet), "margins")],
        ["<h2>Load budget at the worst instant</h2>", _budget_table(sheet), _stow_table(sheet)],
        [
            "<h2>Uncertainty band of the drive physics</h2>",
            "<p>The margins at every corner of the bands' parameter ranges (data/parameter_ranges.yaml); the "
            "speed-torque curve and the days co-simulated again at the worst corner (the lowest bus and loop "
            "gain, the highest rotor damping). The verdict is on the nominal figures; these are beside it.</p>",
            _band_table(sheet),
        ],
        [
            "<h2>Speed-torque curves</h2>",
            _image(speed_torque_png(sheet), "speed-torque curves"),
            _curve_table(sheet),
        ],
        [
            "<h2>Days simulated</h2>",
            f"<p>{html.escape((sheet.get('day_selection') or {}).get('criterion', ''))}</p>",
            _days_table(sheet),
        ],
        ["<h2>Catalogue</h2>", _catalogue_table(sheet)],
    ]


def sizing_html(sheet: Mapping[str, Any]) -> str:
    """The sizing sheet as one HTML page (everything embedded), one section per printed page."""
    head = (
        f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>{sheet_title(sheet)}</title>"
        f"<style>{_STYLE}{PRINT_STYLE}</style></head><body>"
    )
    body = ["<section>\n" + "\n".join(part for part in parts if part) + "\n</section>" for parts in _sections(sheet)]
    return "\n".join([head, *body, "</body></html>"])
