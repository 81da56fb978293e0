"""The report of ``heliostep compare --report``: one self-contained HTML file (parsed with html.parser,
every image decoded from its data URI with matplotlib's PNG reader, nothing pointing at a file), its
Markdown twin, the units in the summary table, and a zoom scaled to the failure's own duration."""

from __future__ import annotations

import base64
import io
from html.parser import HTMLParser

import matplotlib.image
import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
import pytest

from heliostep.plots.compare import failure_window, signal_figure, write_report
from heliostep.results.compare.signal_map import match_signals
from heliostep.results.compare.traces import Tolerance, compare_matched, evaluate_signal

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
T = np.linspace(0.0, 300.0, 30001)  # 10 ms samples over 300 s
TOL = Tolerance(abs=0.01, rel=0.0, time=1e-3)


class _Page(HTMLParser):
    """Every src/href of a page, its table cells and its text."""

    def __init__(self):
        super().__init__()
        self.links: list[tuple[str, str, str]] = []
        self.cells: list[str] = []
        self._cell: list[str] | None = None

    def handle_starttag(self, tag, attrs):
        for key, value in attrs:
            if key in ("src", "href"):
                self.links.append((tag, key, value or ""))
        if tag in ("td", "th"):
            self._cell = []

    def handle_endtag(self, tag):
        if tag in ("td", "th") and self._cell is not None:
            self.cells.append("".join(self._cell).strip())
            self._cell = None

    def handle_data(self, data):
        if self._cell is not None:
            self._cell.append(data)


def _traces():
    """A reference and a vendor-named actual: the torque leaves its tube by 0.05 N.m for 40 ms at 150 s,
    the current by 0.2 A from 200 to 260 s; the angle stays inside."""
    tau, current, angle = np.sin(T / 10), np.cos(T / 20), T / 300
    reference = pd.DataFrame({"time": T, "motor.tau": tau, "motor.i_a": current, "mechanics.theta": angle})
    bump = np.where((T >= 150.0) & (T <= 150.04), 0.06, 0.0)
    drift = np.where((T >= 200.0) & (T <= 260.0), 0.2, 0.0)
    actual = pd.DataFrame({"time": T, "V.tau": tau + bump, "V.i": current + drift, "V.phi": angle})
    ref_meta = {"unit.motor.tau": "N.m", "unit.motor.i_a": "A", "unit.mechanics.theta": "rad"}
    ref_meta.update({"role.torque": "motor.tau", "role.current_a": "motor.i_a", "role.rotor_angle": "mechanics.theta"})
    act_meta = {"role.torque": "V.tau", "role.current_a": "V.i", "role.rotor_angle": "V.phi"}
    return actual, act_meta, reference, ref_meta


@pytest.fixture(scope="module")
def report(tmp_path_factory):
    actual, act_meta, reference, ref_meta = _traces()
    matches = match_signals(list(actual.columns), list(reference.columns), act_meta, ref_meta)
    result = compare_matched(actual, reference, matches, TOL)
    folder = tmp_path_factory.mktemp("report")
    index = write_report(result, actual, reference, folder, act_meta, ref_meta)
    return result, folder, index


def test_the_html_is_self_contained_and_every_image_decodes(report):
    result, folder, index = report
    page = _Page()
    page.feed(index.read_text("utf-8"))
    images = [value for tag, key, value in page.links if tag == "img"]
    assert len(images) == 2 == len(result.failed)
    for tag, key, value in page.links:  # nothing points at a file or the network: data URIs and anchors
        assert value.startswith(("data:image/png;base64,", "#")), (tag, key, value)
    for uri in images:
        png = base64.b64decode(uri.split(",", 1)[1], validate=True)
        assert png[:8] == PNG_SIGNATURE
        pixels = matplotlib.image.imread(io.BytesIO(png), format="png")
        assert pixels.ndim == 3 and pixels.shape[0] > 400 and pixels.shape[1] > 800
        assert np.ptp(pixels[..., :3]) > 0.5  # drawn, not blank
    # the same figures as the PNG files the Markdown twin links
    files = sorted(p.name for p in folder.glob("*.png"))
    assert files == ["motor.i_a.png", "motor.tau.png"]
    assert {base64.b64decode(u.split(",", 1)[1]) for u in images} == {(folder / f).read_bytes() for f in files}


def test_the_summary_table_has_units_matches_and_the_failure_figures(report):
    result, folder, index = report
    page = _Page()
    page.feed(index.read_text("utf-8"))
    head = page.cells[: page.cells.index("plot") + 1]
    rows = [page.cells[i : i + len(head)] for i in range(len(head), len(page.cells), len(head))]
    table = {row[0]: dict(zip(head, row)) for row in rows}
    assert set(table) == {"motor.tau", "motor.i_a", "mechanics.theta"}
    assert [table[s]["unit"] for s in ("motor.tau", "motor.i_a", "mechanics.theta")] == ["N.m", "A", "rad"]
    assert table["motor.tau"]["compared with (how)"] == "V.tau (role torque)"
    assert table["motor.tau"]["verdict"] == "FAIL" and table["mechanics.theta"]["verdict"] == "pass"
    # the worst point of the bump: 0.06 over a tube of half-width 0.01 (abs) widened by the time
    # tolerance along the slope (1e-3 s x |d/dt sin(t/10)| <= 1e-4), between 150 and 150.04 s; 3 digits
    tau = table["motor.tau"]
    assert float(tau["max outside tube"]) == pytest.approx(0.05, abs=2e-4)
    assert 150.0 <= float(tau["at t [s]"]) <= 150.04
    assert float(tau["actual − reference there"]) == pytest.approx(0.06, abs=1e-4)
    assert float(tau["tube half-width there"]) == pytest.approx(0.01, abs=1e-4)
    markdown = (folder / "index.md").read_text("utf-8")
    assert "| `motor.tau` | V.tau (role torque) | N.m | **FAIL** |" in markdown
    assert "(motor.tau.png)" in markdown and "(motor.i_a.png)" in markdown


def _evaluation(name: str):
    actual, _, reference, _ = _traces()
    column = {"motor.tau": "V.tau", "motor.i_a": "V.i"}[name]
    ev = evaluate_signal(T, actual[column].to_numpy(), T, reference[name].to_numpy(), TOL, name=name)
    return ev, (T, reference[name].to_numpy()), (T, actual[column].to_numpy())


def test_the_zoom_is_scaled_to_the_failure_own_duration():
    # a 40 ms failure in a 300 s trace: the zoom spans a few times 40 ms, not seconds
    ev, ref, act = _evaluation("motor.tau")
    lo, hi = failure_window(ev, ref[0], act[0])
    assert lo < 150.0 and hi > 150.04
    assert 0.1 <= hi - lo <= 0.2  # the 40 ms (plus a sample on each side) and its duration on each side
    # a 60 s failure: about three times 60 s
    ev, ref, act = _evaluation("motor.i_a")
    lo, hi = failure_window(ev, ref[0], act[0])
    assert lo == pytest.approx(140.0, abs=0.1) and hi == pytest.approx(300.0)  # clipped at the trace's end


def test_the_figure_has_values_and_a_difference_panel_against_the_tube_half_width():
    ev, ref, act = _evaluation("motor.tau")
    fig = signal_figure(ev, ref, act, unit="N.m")
    try:
        (values, zoom), (difference, zoom_difference) = np.reshape(fig.axes, (2, 2))
        assert zoom.get_xlim() == pytest.approx(failure_window(ev, ref[0], act[0]))
        assert difference.get_ylabel() == "actual - reference [N.m]"
        # the difference panel's band is the tube relative to the reference: +-0.01 N.m, widened by the
        # time tolerance along the slope (at most 1e-3 s x 0.1 N.m/s)
        (band,) = zoom_difference.collections
        y = np.concatenate([path.vertices[:, 1] for path in band.get_paths()])
        assert -0.0101 <= y.min() <= -0.01 and 0.01 <= y.max() <= 0.0101
        (line,) = [ln for ln in zoom_difference.lines if ln.get_label() == "actual - reference"]
        assert np.nanmax(line.get_ydata()) == pytest.approx(0.06)
    finally:
        plt.close(fig)
