"""heliostep.plots.sweep's heat maps: every cell prints its value (the table's, read back from
the figure's texts), and a case that commanded no step says "no steps" instead of "0 N.m"."""

from __future__ import annotations

import numpy as np
import pandas as pd
from matplotlib.backends.backend_agg import FigureCanvasAgg

from heliostep.plots.sweep import HEATMAPS, MAX_ANNOTATED_CELLS, heatmap_figure, plot_heatmap


def _table() -> pd.DataFrame:
    """Days 21, 80, 172 x mirrors 1-3; day 172, mirror 2 commanded no step (peak 0, as a sweep
    writes it), day 80 mirror 3 failed; two currents per cell (the cell shows the larger)."""
    rows = []
    for day in (21, 80, 172):
        for mirror in (1, 2, 3):
            for current, factor in ((4.0, 0.8), (5.5, 1.0)):
                stepless = (day, mirror) == (172, 2)
                failed = (day, mirror) == (80, 3)
                rows.append(
                    {
                        "day_of_year": day,
                        "mirror_index": mirror,
                        "current_A": current,
                        "status": "failed" if failed else "ok",
                        "role": "drive",
                        "steps_commanded": 0 if stepless else 10 + mirror,
                        "peak_torque_Nm": 0.0 if stepless else factor * (1.0 + day / 100 + mirror / 10),
                        "max_tracking_error_deg": 0.01 * mirror,
                    }
                )
    return pd.DataFrame(rows)


def _texts(fig) -> list[str]:
    return [text.get_text() for text in fig.axes[0].texts]


def test_cells_print_their_values_and_no_steps():
    table = _table()
    fig = heatmap_figure(table, "peak_torque_Nm", "peak motor torque [N.m]")
    texts = _texts(fig)
    assert texts.count("no steps") == 1
    expected = {f"{1.0 + day / 100 + mirror / 10:.3g}" for day in (21, 80, 172) for mirror in (1, 2, 3)}
    expected -= {f"{1.0 + 172 / 100 + 2 / 10:.3g}", f"{1.0 + 80 / 100 + 3 / 10:.3g}"}  # no steps, failed
    assert sorted(t for t in texts if t != "no steps") == sorted(expected)
    assert "0" not in texts and "0.0" not in texts
    (legend,) = fig.legends
    assert [t.get_text() for t in legend.get_texts()] == ["no steps"]
    renderer = FigureCanvasAgg(fig).get_renderer()
    fig.draw(renderer)
    box = legend.get_window_extent(renderer)
    for artist in (fig.axes[0], fig.axes[0].title, fig.axes[0].xaxis.label):  # over no cell, title or axis label
        assert not box.overlaps(artist.get_window_extent(renderer))
    where = next(t for t in fig.axes[0].texts if t.get_text() == "no steps").get_position()
    assert where == (2, 1)  # day 172 (third column), mirror 2 (second row)


def test_a_stepless_case_has_its_value_in_figures_that_do_not_need_steps():
    fig = heatmap_figure(_table(), "max_tracking_error_deg", "max secondary tracking error [deg]")
    texts = _texts(fig)
    assert "no steps" not in texts and texts.count("0.02") == 3  # mirror 2 on every day, day 172 without steps too
    assert texts.count("0.03") == 2  # mirror 3: day 80 failed
    assert fig.axes[0].get_legend() is None and not fig.legends


def test_a_peak_missing_is_no_steps_and_big_maps_are_not_annotated(tmp_path):
    table = _table()
    table.loc[(table["day_of_year"] == 21) & (table["mirror_index"] == 1), "peak_torque_Nm"] = np.nan
    table.loc[(table["day_of_year"] == 21) & (table["mirror_index"] == 1), "steps_commanded"] = pd.NA
    assert _texts(heatmap_figure(table, "peak_torque_Nm", "peak")).count("no steps") == 2
    days = np.arange(1, MAX_ANNOTATED_CELLS // 13 + 2)
    big = pd.DataFrame(
        [
            {"day_of_year": d, "mirror_index": m, "status": "ok", "steps_commanded": 5, "peak_torque_Nm": 1.0}
            for d in days
            for m in range(1, 14)
        ]
    )
    assert len(big) > MAX_ANNOTATED_CELLS and _texts(heatmap_figure(big, "peak_torque_Nm", "peak")) == []
    path = plot_heatmap(table, "peak_torque_Nm", tmp_path / HEATMAPS[0][1], HEATMAPS[0][2])
    assert path is not None and path.read_bytes()[:4] == b"\x89PNG"
