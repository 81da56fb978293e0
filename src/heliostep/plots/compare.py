"""Plots and the report folder of ``heliostep compare``.

:func:`write_report` writes, into one folder, a PNG per failing signal (reference,
tolerance tube as a shaded band, actual, the parts outside the tube in red, and a
zoom around the worst point) and an index (``index.md`` and ``index.html``) that
lists every compared signal with its verdict and links the PNGs.
"""

from __future__ import annotations

import html
import re
from collections.abc import Mapping
from pathlib import Path
from urllib.parse import quote

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd

from heliostep.plots.thinning import thin
from heliostep.results.compare import (
    ComparisonResult,
    SignalEvaluation,
    SignalResult,
    evaluate_signal,
)
from heliostep.results.trace_io import TIME

__all__ = ["plot_signal", "write_report", "png_name"]

#: Drawn points per series and panel at most (extremes per time bin are kept).
MAX_POINTS = 4000


def png_name(signal: str) -> str:
    """File name of a signal's plot: the name with unsafe characters replaced."""
    stem = re.sub(r"[^A-Za-z0-9._-]", "_", signal).strip(".") or "signal"
    return f"{stem}.png"


def _thin(t: np.ndarray, *series: np.ndarray) -> np.ndarray:
    """At most :data:`MAX_POINTS` indices to draw (see :func:`heliostep.plots.thinning.thin`)."""
    return thin(t, *series, max_buckets=max(1, MAX_POINTS // (2 + 2 * len(series))))


def _range(t: np.ndarray, lo: float, hi: float) -> slice:
    """Slice of sorted *t* covering ``[lo, hi]`` plus one sample on each side."""
    i = max(int(np.searchsorted(t, lo, side="left")) - 1, 0)
    j = min(int(np.searchsorted(t, hi, side="right")) + 1, t.size)
    return slice(i, j)


def _draw(ax, ev: SignalEvaluation, ref_t, ref_y, act_t, act_y, lo: float, hi: float) -> None:
    rs, as_ = _range(ref_t, lo, hi), _range(act_t, lo, hi)
    rt, ry = ref_t[rs], ref_y[rs]
    at, ay = act_t[as_], act_y[as_]
    if ev.time.size:
        es = _range(ev.time, lo, hi)
        et, low, up, ea, ex = ev.time[es], ev.lower[es], ev.upper[es], ev.actual[es], ev.excess[es]
        k = _thin(et, low, up)
        ax.fill_between(et[k], low[k], up[k], color="tab:blue", alpha=0.2, linewidth=0, label="tolerance tube")
    k = _thin(rt, ry)
    ax.plot(rt[k], ry[k], color="tab:blue", linewidth=1.0, label="reference")
    k = _thin(at, ay)
    ax.plot(at[k], ay[k], color="black", linewidth=0.8, linestyle="--", label="actual")
    if ev.time.size:
        idx = np.flatnonzero(ex > 0)
        if idx.size:
            idx = idx[_thin(et[idx], ea[idx])]
            # Red line along runs of consecutive violating grid points, a marker on each.
            gap = np.flatnonzero(np.diff(idx) > 1) + 1
            line_t = np.insert(et[idx], gap, np.nan)
            line_y = np.insert(ea[idx], gap, np.nan)
            ax.plot(line_t, line_y, color="red", linewidth=2.0)
            ax.plot(et[idx], ea[idx], "o", color="red", markersize=2.5, label="outside tube")
    if hi > lo:
        ax.set_xlim(lo, hi)
    ax.grid(True, alpha=0.3)


def plot_signal(
    evaluation: SignalEvaluation,
    path: str | Path,
    reference: tuple[np.ndarray, np.ndarray],
    actual: tuple[np.ndarray, np.ndarray],
    unit: str | None = None,
    time_unit: str = "s",
) -> Path:
    """Write the PNG of one signal: a full view and a zoom around the worst point.

    *reference* and *actual* are ``(time, values)`` of the traces as sampled.
    """
    path = Path(path)
    r: SignalResult = evaluation.result
    ref_t, ref_y = (np.asarray(a, dtype=float) for a in reference)
    act_t, act_y = (np.asarray(a, dtype=float) for a in actual)
    t0 = min(ref_t[0], act_t[0])
    t1 = max(ref_t[-1], act_t[-1])
    ylabel = f"{r.name} [{unit}]" if unit else r.name
    xlabel = f"{TIME} [{time_unit}]"

    fig, (full, zoom) = plt.subplots(2, 1, figsize=(10, 7.5), layout="constrained")
    verdict = "passed" if r.passed else "FAILED"
    worst = (
        f"max {r.max_excess:.3g}{' ' + unit if unit else ''} outside the tube "
        f"at t = {r.time_max_excess:.6g} {time_unit}"
        if np.isfinite(r.max_excess) and r.max_excess > 0
        else (r.note or "inside the tube")
    )
    fig.suptitle(f"{r.name}: {verdict} — {worst}", fontsize=11)
    _draw(full, evaluation, ref_t, ref_y, act_t, act_y, t0, t1)
    full.set_title(
        f"tolerance abs {r.tolerance.abs:g}, rel {r.tolerance.rel:g}, time {r.tolerance.time:g} {time_unit}; "
        f"outside the tube {100 * r.outside_fraction:.3g} % of the time",
        fontsize=9,
    )
    full.set_xlabel(xlabel)
    full.set_ylabel(ylabel)
    full.legend(loc="best", fontsize=8)

    tau = r.tolerance.time
    if np.isfinite(r.max_excess) and r.max_excess > 0:
        centre = r.time_max_excess
    elif act_t[-1] < ref_t[-1] - tau:  # the actual stops early
        centre = act_t[-1]
    elif act_t[0] > ref_t[0] + tau:  # the actual starts late
        centre = act_t[0]
    else:
        centre = 0.5 * (t0 + t1)
    half = _zoom_half_width(evaluation, centre, t1 - t0)
    _draw(zoom, evaluation, ref_t, ref_y, act_t, act_y, max(centre - half, t0), min(centre + half, t1))
    zoom.axvline(centre, color="red", linewidth=0.8, alpha=0.6)
    zoom.set_title(f"zoom around t = {centre:.6g} {time_unit}", fontsize=9)
    zoom.set_xlabel(xlabel)
    zoom.set_ylabel(ylabel)
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path


def _zoom_half_width(ev: SignalEvaluation, centre: float, duration: float) -> float:
    """Half-width of the zoom: covers the violation around *centre*, a few time tolerances."""
    half = max(5 * ev.result.tolerance.time, 0.01 * duration)
    if ev.time.size:
        bad = ev.excess > 0
        k = int(np.searchsorted(ev.time, centre))
        k = min(k, ev.time.size - 1)
        if bad[k]:
            i = k
            while i > 0 and bad[i - 1]:
                i -= 1
            j = k
            while j < bad.size - 1 and bad[j + 1]:
                j += 1
            half = max(half, 1.5 * max(centre - ev.time[i], ev.time[j] - centre))
        else:
            spacing = np.diff(ev.time[max(k - 3, 0) : k + 4])
            if spacing.size:
                half = max(half, 4 * float(spacing.max()))
    return half if half > 0 else 1.0


def _fmt(x: float | None, spec: str = ".3g") -> str:
    return "–" if x is None or not np.isfinite(x) else format(x, spec)


def write_report(
    result: ComparisonResult,
    actual: pd.DataFrame,
    reference: pd.DataFrame,
    directory: str | Path,
    actual_metadata: Mapping[str, str] | None = None,
    reference_metadata: Mapping[str, str] | None = None,
) -> Path:
    """Write the report folder (created if needed); returns the path of ``index.html``.

    One PNG per *failing* signal, named by :func:`png_name`; units come from the
    ``unit.<column>`` metadata (reference first, then actual).
    """
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    actual_metadata = dict(actual_metadata or {})
    reference_metadata = dict(reference_metadata or {})
    units = {**actual_metadata, **reference_metadata}
    time_unit = units.get(f"unit.{TIME}", "s")
    ta = actual[TIME].to_numpy(dtype=float)
    tr = reference[TIME].to_numpy(dtype=float)

    pngs: dict[str, str] = {}
    used: set[str] = set()
    for name, r in result.signals.items():
        if r.passed:
            continue
        file = png_name(name)
        n = 2
        while file.lower() in used:
            file = png_name(name)[:-4] + f"-{n}.png"
            n += 1
        used.add(file.lower())
        ya = actual[name].to_numpy(dtype=float)
        yr = reference[name].to_numpy(dtype=float)
        ev = evaluate_signal(ta, ya, tr, yr, r.tolerance, name=name)
        plot_signal(ev, directory / file, (tr, yr), (ta, ya), unit=units.get(f"unit.{name}"), time_unit=time_unit)
        pngs[name] = file

    (directory / "index.md").write_text(_markdown(result, pngs, actual_metadata, reference_metadata), "utf-8")
    index = directory / "index.html"
    index.write_text(_html(result, pngs, actual_metadata, reference_metadata), "utf-8")
    return index


_HEAD = (
    "signal",
    "verdict",
    "max outside tube",
    "at t",
    "max |diff|",
    "at t",
    "time outside",
    "tolerance abs / rel / time",
)


def _row(r: SignalResult) -> list[str]:
    tol = r.tolerance
    return [
        r.name,
        "pass" if r.passed else "FAIL",
        _fmt(r.max_excess),
        _fmt(r.time_max_excess if r.max_excess > 0 else None, ".6g"),
        _fmt(r.max_abs_diff),
        _fmt(r.time_max_abs_diff if r.max_abs_diff > 0 else None, ".6g"),
        f"{100 * r.outside_fraction:.3g} %",
        f"{tol.abs:g} / {tol.rel:g} / {tol.time:g}",
    ]


def _complete(meta: Mapping[str, str]) -> str:
    value = meta.get("complete")
    return "" if value is None else f" (complete: {value})"


def _summary(result: ComparisonResult) -> str:
    failed = result.failed
    if not failed:
        return f"PASS: all {len(result.signals)} signal(s) inside their tolerance tube"
    return f"FAIL: {len(failed)} of {len(result.signals)} signal(s) outside their tolerance tube"


def _md_cell(text: str) -> str:
    return text.replace("|", "\\|")


def _markdown(result, pngs, actual_meta, reference_meta) -> str:
    lines = [
        "# heliostep compare",
        "",
        f"- actual: `{result.actual_name}`{_complete(actual_meta)}",
        f"- reference: `{result.reference_name}`{_complete(reference_meta)}",
        f"- **{_summary(result)}**",
    ]
    if result.only_in_actual:
        lines.append(f"- not compared, only in actual: {', '.join(f'`{s}`' for s in result.only_in_actual)}")
    if result.only_in_reference:
        lines.append(f"- not compared, only in reference: {', '.join(f'`{s}`' for s in result.only_in_reference)}")
    lines += ["", "| " + " | ".join(_md_cell(h) for h in _HEAD) + " | plot |", "|" + "---|" * (len(_HEAD) + 1)]
    for name, r in result.signals.items():
        cells = _row(r)
        cells[0] = f"`{cells[0]}`"
        cells[1] = f"**{cells[1]}**" if not r.passed else cells[1]
        plot = f"[plot]({quote(pngs[name])})" if name in pngs else ""
        lines.append("| " + " | ".join(_md_cell(c) for c in [*cells, plot]) + " |")
    notes = [(name, r.note) for name, r in result.signals.items() if r.note]
    if notes:
        lines += ["", "Notes:", ""] + [f"- `{name}`: {note}" for name, note in notes]
    for name, file in pngs.items():
        lines += ["", f"## `{name}`", "", f"![{name}]({quote(file)})"]
    return "\n".join(lines) + "\n"


def _html(result, pngs, actual_meta, reference_meta) -> str:
    e = html.escape
    ok = result.passed
    parts = [
        "<!DOCTYPE html>",
        '<html lang="en"><head><meta charset="utf-8"><title>heliostep compare</title>',
        "<style>body{font-family:sans-serif;margin:2em}table{border-collapse:collapse}"
        "td,th{border:1px solid #ccc;padding:3px 8px;text-align:right}td:first-child{text-align:left}"
        ".fail{background:#fdd}.pass{background:#dfd}img{max-width:100%}</style></head><body>",
        "<h1>heliostep compare</h1>",
        "<ul>",
        f"<li>actual: <code>{e(result.actual_name)}</code>{e(_complete(actual_meta))}</li>",
        f"<li>reference: <code>{e(result.reference_name)}</code>{e(_complete(reference_meta))}</li>",
    ]
    if result.only_in_actual:
        parts.append(f"<li>not compared, only in actual: {e(', '.join(result.only_in_actual))}</li>")
    if result.only_in_reference:
        parts.append(f"<li>not compared, only in reference: {e(', '.join(result.only_in_reference))}</li>")
    parts += [
        "</ul>",
        f'<p class="{"pass" if ok else "fail"}"><strong>{e(_summary(result))}</strong></p>',
        "<table><tr>" + "".join(f"<th>{e(h)}</th>" for h in (*_HEAD, "plot")) + "</tr>",
    ]
    for name, r in result.signals.items():
        cells = [e(c) for c in _row(r)]
        cells[0] = f"<code>{cells[0]}</code>"
        link = f'<a href="#{e(quote(name))}">plot</a>' if name in pngs else ""
        if r.note:
            cells[1] += f' <span title="{e(r.note)}">(note)</span>'
        parts.append(
            f'<tr class="{"pass" if r.passed else "fail"}">'
            + "".join(f"<td>{c}</td>" for c in [*cells, link])
            + "</tr>"
        )
    parts.append("</table>")
    for name, r in result.signals.items():
        if r.note:
            parts.append(f"<p><code>{e(name)}</code>: {e(r.note)}</p>")
    for name, file in pngs.items():
        parts += [
            f'<h2 id="{e(quote(name))}"><code>{e(name)}</code></h2>',
            f'<p><a href="{e(quote(file))}"><img src="{e(quote(file))}" alt="{e(name)}"></a></p>',
        ]
    parts.append("</body></html>")
    return "\n".join(parts) + "\n"
