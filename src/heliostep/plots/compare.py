"""Plots and the report of ``heliostep compare``: a self-contained ``index.html``, its Markdown twin,
one figure per failing signal.

Details: docs/compare.md, ``heliostep.plots.compare``.
"""

from __future__ import annotations

import base64
import html
import io
import re
from collections.abc import Mapping
from pathlib import Path
from urllib.parse import quote

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
from matplotlib.figure import Figure

from heliostep.plots.png import save_png
from heliostep.plots.thinning import Band, min_max_line
from heliostep.results.compare.signal_map import signal_units
from heliostep.results.compare.traces import ComparisonResult, SignalEvaluation, SignalResult, evaluate_signal
from heliostep.results.compare.verdicts import failure_message
from heliostep.results.trace.files import TIME

__all__ = ["failure_window", "png_name", "signal_figure", "write_report"]

#: Time bins a long series is thinned to (its least and largest value in each drawn, :func:`min_max_line`).
BINS = 1000


def png_name(signal: str) -> str:
    """File name of a signal's plot: the name with unsafe characters replaced."""
    stem = re.sub(r"[^A-Za-z0-9._-]", "_", signal).strip(".") or "signal"
    return f"{stem}.png"


def _tube(ax, t: np.ndarray, low: np.ndarray, up: np.ndarray, label: str) -> None:
    """The tube between ``low`` and ``up``: over a long span, from the least of ``low`` to the largest of
    ``up`` per bin."""
    lower, upper = (Band.of_rows(t, low, BINS), Band.of_rows(t, up, BINS)) if len(t) > 2 * BINS else (None, None)
    if lower is not None and upper is not None:
        t, low, up = lower.edges, np.r_[lower.low, lower.low[-1]], np.r_[upper.high, upper.high[-1]]
        ax.fill_between(t, low, up, step="post", color="tab:blue", alpha=0.2, linewidth=0, label=label)
        return
    ax.fill_between(t, low, up, color="tab:blue", alpha=0.2, linewidth=0, label=label)


def _range(t: np.ndarray, lo: float, hi: float) -> slice:
    """Slice of sorted *t* covering ``[lo, hi]`` plus one sample on each side."""
    i = max(int(np.searchsorted(t, lo, side="left")) - 1, 0)
    j = min(int(np.searchsorted(t, hi, side="right")) + 1, t.size)
    return slice(i, j)


def _outside(ax, t: np.ndarray, y: np.ndarray, excess: np.ndarray, label: str | None) -> None:
    """Red line along runs of consecutive grid points outside the tube, a marker on each."""
    idx = np.flatnonzero(excess > 0)
    if not idx.size:
        return
    if idx.size > 2 * BINS:  # thinned: the runs drawn as one line
        shown_t, shown_y = min_max_line(t[idx], y[idx], BINS)
        ax.plot(shown_t, shown_y, color="red", linewidth=2.0)
    else:
        gap = np.flatnonzero(np.diff(idx) > 1) + 1
        shown_t, shown_y = t[idx], y[idx]
        ax.plot(np.insert(shown_t, gap, np.nan), np.insert(shown_y, gap, np.nan), color="red", linewidth=2.0)
    ax.plot(shown_t, shown_y, "o", color="red", markersize=2.5, label=label)


def _draw_values(ax, ev: SignalEvaluation, ref, act, lo: float, hi: float) -> None:
    (ref_t, ref_y), (act_t, act_y) = ref, act
    if ev.time.size:
        es = _range(ev.time, lo, hi)
        et, low, up = ev.time[es], ev.lower[es], ev.upper[es]
        _tube(ax, et, low, up, "tolerance tube")
    rs, as_ = _range(ref_t, lo, hi), _range(act_t, lo, hi)
    ax.plot(*min_max_line(ref_t[rs], ref_y[rs], BINS), color="tab:blue", linewidth=1.0, label="reference")
    shown = min_max_line(act_t[as_], act_y[as_], BINS)
    ax.plot(*shown, color="black", linewidth=0.8, linestyle="--", label="actual")
    if ev.time.size:
        _outside(ax, et, ev.actual[es], ev.excess[es], "outside tube")
    if hi > lo:
        ax.set_xlim(lo, hi)
    ax.grid(True, alpha=0.3)


def _draw_difference(ax, ev: SignalEvaluation, lo: float, hi: float) -> None:
    """``actual - reference`` against the tube's edges relative to the reference."""
    if ev.time.size:
        es = _range(ev.time, lo, hi)
        et, ref = ev.time[es], ev.reference[es]
        below, above, diff = ev.lower[es] - ref, ev.upper[es] - ref, ev.actual[es] - ref
        _tube(ax, et, below, above, "tube - reference")
        ax.plot(*min_max_line(et, diff, BINS), color="black", linewidth=0.8, label="actual - reference")
        _outside(ax, et, diff, ev.excess[es], None)
    ax.axhline(0.0, color="tab:blue", linewidth=0.6)
    if hi > lo:
        ax.set_xlim(lo, hi)
    ax.grid(True, alpha=0.3)


def failure_window(ev: SignalEvaluation, reference_time: np.ndarray, actual_time: np.ndarray) -> tuple[float, float]:
    """The zoom's time span [s]: the contiguous stretch outside the tube around the worst point,
    widened on each side by its own duration (at least two time tolerances and three reference
    samples), so the failure fills about a third of the zoom; a truncated actual: around its end."""
    r = ev.result
    tau = r.tolerance.time
    t0, t1 = min(reference_time[0], actual_time[0]), max(reference_time[-1], actual_time[-1])
    if ev.time.size and np.isfinite(r.max_excess) and r.max_excess > 0:
        bad = ev.excess > 0
        k = min(int(np.searchsorted(ev.time, r.time_max_excess)), ev.time.size - 1)
        while k + 1 < bad.size and not bad[k] and ev.time[k + 1] == ev.time[k]:
            k += 1  # the worst may be the right limit of a jump
        i = j = k
        while i > 0 and bad[i - 1]:
            i -= 1
        while j < bad.size - 1 and bad[j + 1]:
            j += 1
        start, end = float(ev.time[i]), float(ev.time[j])
    else:
        centre = actual_time[-1] if actual_time[-1] < reference_time[-1] - tau else actual_time[0]
        start = end = float(centre if not r.passed else 0.5 * (t0 + t1))
    near = reference_time[max(int(np.searchsorted(reference_time, start)) - 3, 0) :][:7]
    spacing = float(np.diff(near).max()) if near.size > 1 else 0.0
    margin = max(end - start, 2 * tau, 3 * spacing)
    if margin <= 0:
        margin = 0.01 * (t1 - t0) or 1.0
    return max(start - margin, t0), min(end + margin, t1)


def signal_figure(
    evaluation: SignalEvaluation,
    reference: tuple[np.ndarray, np.ndarray],
    actual: tuple[np.ndarray, np.ndarray],
    unit: str | None = None,
    time_unit: str = "s",
    actual_label: str | None = None,
) -> Figure:
    """The figure of one signal (four panels, see the module); *reference* and *actual* are
    ``(time, values)`` as sampled. The caller closes it."""
    r: SignalResult = evaluation.result
    ref = tuple(np.asarray(a, dtype=float) for a in reference)
    act = tuple(np.asarray(a, dtype=float) for a in actual)
    t0, t1 = min(ref[0][0], act[0][0]), max(ref[0][-1], act[0][-1])
    ylabel = f"{r.name} [{unit}]" if unit else r.name
    fig, axes = plt.subplots(
        2, 2, figsize=(13, 7.5), layout="constrained", sharex="col", gridspec_kw={"height_ratios": [3, 2]}
    )
    verdict = "passed" if r.passed else "FAILED"
    compared = f" (actual: {actual_label})" if actual_label and actual_label != r.name else ""
    fig.suptitle(f"{r.name}{compared}: {verdict} — {failure_message(r, unit, time_unit)}", fontsize=10)
    lo, hi = failure_window(evaluation, ref[0], act[0])
    for column, (a, b) in enumerate(((t0, t1), (lo, hi))):
        _draw_values(axes[0, column], evaluation, ref, act, a, b)
        _draw_difference(axes[1, column], evaluation, a, b)
        axes[1, column].set_xlabel(f"{TIME} [{time_unit}]")
        axes[1, column].ticklabel_format(axis="x", useOffset=False)  # a zoom at 150 s reads 150.02, not +1.5e2
    axes[0, 0].set_ylabel(ylabel)
    axes[1, 0].set_ylabel(f"actual - reference [{unit}]" if unit else "actual - reference")
    tol = r.tolerance
    axes[0, 0].set_title(
        f"whole span; tolerance abs {tol.abs:g}, rel {tol.rel:g}, time {tol.time:g} {time_unit}; "
        f"outside the tube {100 * r.outside_fraction:.3g} % of the time",
        fontsize=9,
    )
    axes[0, 1].set_title(f"zoom: {lo:.6g} to {hi:.6g} {time_unit} ({hi - lo:.3g} {time_unit})", fontsize=9)
    if np.isfinite(r.time_max_excess) and r.max_excess > 0:
        for ax in axes[:, 1]:
            ax.axvline(r.time_max_excess, color="red", linewidth=0.8, alpha=0.6)
    axes[0, 0].legend(loc="best", fontsize=8)
    axes[1, 0].legend(loc="best", fontsize=8)
    return fig


def write_report(
    result: ComparisonResult,
    actual: pd.DataFrame,
    reference: pd.DataFrame,
    directory: str | Path,
    actual_metadata: Mapping[str, str] | None = None,
    reference_metadata: Mapping[str, str] | None = None,
) -> Path:
    """Write the report folder (created if needed); returns the path of ``index.html``.

    Units come from the ``unit.<column>`` metadata (the reference's, else the actual's matched
    column). Existing files of the same names are overwritten, others left alone.
    """
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    actual_metadata, reference_metadata = dict(actual_metadata or {}), dict(reference_metadata or {})
    units = signal_units({n: result.match_of(n) for n in result.signals}, actual_metadata, reference_metadata)
    time_unit = units.get(TIME, "s")
    ta, tr = actual[TIME].to_numpy(dtype=float), reference[TIME].to_numpy(dtype=float)
    pngs: dict[str, tuple[str, bytes]] = {}
    used: set[str] = set()
    for name, r in result.signals.items():
        if r.passed:
            continue
        file, n = png_name(name), 2
        while file.lower() in used:
            file, n = png_name(name)[:-4] + f"-{n}.png", n + 1
        used.add(file.lower())
        column = result.match_of(name).actual
        ya, yr = actual[column].to_numpy(dtype=float), reference[name].to_numpy(dtype=float)
        ev = evaluate_signal(ta, ya, tr, yr, r.tolerance, name=name)
        fig = signal_figure(ev, (tr, yr), (ta, ya), units.get(name), time_unit, column)
        buffer = io.BytesIO()
        try:
            save_png(fig, buffer, 90)
        finally:
            plt.close(fig)
        pngs[name] = (file, buffer.getvalue())
        (directory / file).write_bytes(pngs[name][1])
    meta = (actual_metadata, reference_metadata)
    (directory / "index.md").write_text(_markdown(result, {n: f for n, (f, _) in pngs.items()}, units, *meta), "utf-8")
    index = directory / "index.html"
    index.write_text(_html(result, {n: png for n, (_, png) in pngs.items()}, units, *meta), "utf-8")
    return index


def _fmt(x: float | None, spec: str = ".3g") -> str:
    return "–" if x is None or not np.isfinite(x) else format(x, spec)


_HEAD = (
    "signal",
    "compared with (how)",
    "unit",
    "verdict",
    "max outside tube",
    "at t [s]",
    "actual − reference there",
    "tube half-width there",
    "max |diff|",
    "at t [s]",
    "time outside",
    "tolerance abs / rel / time [s]",
)


def _row(result: ComparisonResult, r: SignalResult, units: Mapping[str, str]) -> list[str]:
    tol, match = r.tolerance, result.match_of(r.name)
    failing = r.max_excess > 0
    how = f"role {match.role}" if match.how == "role" else match.how
    return [
        r.name,
        f"{match.actual} ({how})",
        units.get(r.name, "–"),
        "pass" if r.passed else "FAIL",
        _fmt(r.max_excess),
        _fmt(r.time_max_excess if failing else None, ".6g"),
        _fmt(r.deviation_at_max_excess if failing else None),
        _fmt(r.half_width_at_max_excess if failing else None),
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


def _facts(result: ComparisonResult, actual_meta, reference_meta) -> list[str]:
    facts = [
        f"actual: {result.actual_name}{_complete(actual_meta)}",
        f"reference: {result.reference_name}{_complete(reference_meta)}",
    ]
    if result.only_in_actual:
        facts.append(f"not compared, only in actual: {', '.join(result.only_in_actual)}")
    if result.only_in_reference:
        facts.append(f"not compared, only in reference: {', '.join(result.only_in_reference)}")
    return facts


def _md_cell(text: str) -> str:
    return text.replace("|", "\\|")


def _markdown(result, pngs, units, actual_meta, reference_meta) -> str:
    lines = ["# heliostep compare", ""] + [f"- {_md_cell(f)}" for f in _facts(result, actual_meta, reference_meta)]
    lines += [f"- **{_summary(result)}**", ""]
    lines += ["| " + " | ".join(_HEAD) + " | plot |", "|" + "---|" * (len(_HEAD) + 1)]
    for name, r in result.signals.items():
        cells = _row(result, r, units)
        cells[0] = f"`{cells[0]}`"
        cells[3] = f"**{cells[3]}**" if not r.passed else cells[3]
        plot = f"[plot]({quote(pngs[name])})" if name in pngs else ""
        lines.append("| " + " | ".join(_md_cell(c) for c in [*cells, plot]) + " |")
    notes = [(name, r.note) for name, r in result.signals.items() if r.note]
    if notes:
        lines += ["", "Notes:", ""] + [f"- `{name}`: {note}" for name, note in notes]
    for name, file in pngs.items():
        message = failure_message(result.signals[name], units.get(name))
        lines += ["", f"## `{name}`", "", _md_cell(message), "", f"![{name}]({quote(file)})"]
    return "\n".join(lines) + "\n"


_STYLE = (
    "body{font-family:sans-serif;margin:2em}table{border-collapse:collapse;font-size:0.85em}"
    "td,th{border:1px solid #ccc;padding:3px 6px;text-align:right}td:first-child,td:nth-child(2){text-align:left}"
    "th,td:first-child,td:nth-child(2){overflow-wrap:anywhere}"
    ".fail{background:#fdd}.pass{background:#dfd}img{max-width:100%}"
)


def _html(result, pngs: Mapping[str, bytes], units, actual_meta, reference_meta) -> str:
    e = html.escape
    parts = [
        "<!DOCTYPE html>",
        f'<html lang="en"><head><meta charset="utf-8"><title>heliostep compare</title><style>{_STYLE}</style>',
        "</head><body>",
        "<h1>heliostep compare</h1>",
        "<ul>" + "".join(f"<li>{e(f)}</li>" for f in _facts(result, actual_meta, reference_meta)) + "</ul>",
        f'<p class="{"pass" if result.passed else "fail"}"><strong>{e(_summary(result))}</strong></p>',
        "<table><tr>" + "".join(f"<th>{e(h)}</th>" for h in (*_HEAD, "plot")) + "</tr>",
    ]
    for name, r in result.signals.items():
        cells = [e(c) for c in _row(result, r, units)]
        cells[0] = f"<code>{cells[0]}</code>"
        link = f'<a href="#{e(quote(name))}">plot</a>' if name in pngs else ""
        if r.note:
            cells[3] += f' <span title="{e(r.note)}">(note)</span>'
        row_class = "pass" if r.passed else "fail"
        parts.append(f'<tr class="{row_class}">' + "".join(f"<td>{c}</td>" for c in [*cells, link]) + "</tr>")
    parts.append("</table>")
    parts += [f"<p><code>{e(name)}</code>: {e(r.note)}</p>" for name, r in result.signals.items() if r.note]
    for name, png in pngs.items():
        data = base64.b64encode(png).decode("ascii")
        parts += [
            f'<h2 id="{e(quote(name))}"><code>{e(name)}</code></h2>',
            f"<p>{e(failure_message(result.signals[name], units.get(name)))}</p>",
            f'<p><img src="data:image/png;base64,{data}" alt="{e(name)}"></p>',
        ]
    parts.append("</body></html>")
    return "\n".join(parts) + "\n"
