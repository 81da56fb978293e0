"""heliostep's HTML pages in a real browser: the sizing sheet (``heliostep size``) and the compare report
(``heliostep compare --report``), made by the commands at a small size and rendered by headless Chromium
(tests/support/browser.py). Laid out in a window an A4 page wide (794 CSS px), every image has loaded and
decoded, and nothing reaches past the page's right edge (no horizontal scroll, no element's box beyond it);
a screenshot decodes to a drawn PNG of the window, and the page prints to a PDF of at least one page (the
sizing sheet: one at least per section, each starting a page). Skipped, saying why, where no ``chromium``
can be had (``.ci/run`` installs Debian's)."""

from __future__ import annotations

from pathlib import Path

import matplotlib.image
import numpy as np
import pandas as pd
import pytest
import yaml

from browser import A4_HEIGHT, A4_WIDTH, chromium, measure, pdf_pages, print_pdf, screenshot
from catalogue_entries import QSH8618_65_AT_3A
from heliostep.cli import main
from heliostep.paths import scenarios_dir
from heliostep.results.trace.files import write_trace

pytestmark = pytest.mark.skipif(
    chromium() is None, reason="no `chromium` on PATH to render the pages (Debian: apt-get install chromium)"
)

T = np.linspace(0.0, 10.0, 1001)


@pytest.fixture(scope="module")
def sizing_sheet(tmp_path_factory, fmu_paths) -> Path:
    """``sizing.html`` of one candidate at one current on one day's 20 s window, without band days."""
    folder = tmp_path_factory.mktemp("sheet")
    catalogue = folder / "motors.yaml"
    catalogue.write_text(yaml.safe_dump({"motors": {"small": QSH8618_65_AT_3A}}), encoding="utf-8")
    argv = ["size", str(scenarios_dir() / "jan21-central.yaml"), "--catalogue", str(catalogue), "--days", "21"]
    argv += ["--curve-rates", "5", "--no-band-days", "--design-gust", "25", "--set", "window.duration=20"]
    assert main([*argv, "--out", str(folder / "out")]) == 0
    return folder / "out" / "sizing.html"


@pytest.fixture(scope="module")
def compare_report(tmp_path_factory) -> Path:
    """``index.html`` of a compare in which two of three signals fail (one with a long unbroken name)."""
    folder = tmp_path_factory.mktemp("compare")
    signals = {"motor.tau": np.sin(T), "panel_angle_error_of_the_far_mirror": np.cos(T), "rate": 0.5 * T}
    failing = {**signals, "motor.tau": signals["motor.tau"] + 0.5, "rate": np.where(T > 7.0, 1.0 + 0.5 * T, 0.5 * T)}
    write_trace(pd.DataFrame({"time": T, **signals}), folder / "ref.parquet", {"unit.motor.tau": "N.m"})
    write_trace(pd.DataFrame({"time": T, **failing}), folder / "act.csv")
    report = folder / "report"
    assert main(["compare", str(folder / "act.csv"), str(folder / "ref.parquet"), "--report", str(report)]) == 1
    return report / "index.html"


#: page -> (its fixture, how many images it embeds)
PAGES = {"sizing sheet": ("sizing_sheet", 2), "compare report": ("compare_report", 2)}


@pytest.fixture(scope="module", params=list(PAGES))
def page(request) -> tuple[Path, int]:
    fixture, images = PAGES[request.param]
    return request.getfixturevalue(fixture), images


def test_every_image_decodes_and_nothing_is_wider_than_an_a4_page(page):
    path, images = page
    found = measure(path, A4_WIDTH, A4_HEIGHT)
    assert len(found["images"]) == images
    for image in found["images"]:
        assert image["complete"] and image["naturalWidth"] > 0, image
        assert 0 < image["width"] <= found["clientWidth"], image
    assert found["scrollWidth"] <= found["clientWidth"] <= A4_WIDTH
    assert found["wider"] == []  # each as (tag, class, right edge [CSS px], the section's heading)


def test_the_page_screenshots_and_prints_to_a_pdf(page, tmp_path):
    path, _ = page
    png = screenshot(path, tmp_path / "page.png", A4_WIDTH, A4_HEIGHT)
    pixels = matplotlib.image.imread(png, format="png")
    assert pixels.shape[:2] == (A4_HEIGHT, A4_WIDTH)
    assert np.ptp(pixels[..., :3]) > 0.5  # drawn, not blank
    pdf = print_pdf(path, tmp_path / "page.pdf").read_bytes()
    assert pdf.startswith(b"%PDF-")
    assert pdf_pages(pdf) >= max(1, path.read_text("utf-8").count("<section>"))
