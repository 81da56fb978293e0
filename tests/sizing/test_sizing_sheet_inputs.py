"""A sizing sheet says what it was sized for: ``sizing.json``'s ``inputs`` block holds the scenario as resolved
(every ``--set`` over it), the wind, the files' sha256 as read and the versions a run's metadata records;
``sizing.html`` opens with the site in its title and the verdict paragraph (the drive chosen, its governing case,
its margin), then the inputs, one printed page per section. Without any wind ``size`` refuses, exit 2.

The sizing runs for real at 37 N (one candidate at one current, one day, a 20 s window, no band days)."""

from __future__ import annotations

import hashlib
import json
import platform
import time
from html.parser import HTMLParser
from importlib import metadata
from pathlib import Path

import pytest
import yaml

import heliostep
from catalogue_entries import QSH8618_65_AT_3A
from heliostep.cli import main
from heliostep.paths import scenarios_dir
from heliostep.scenario import load_scenario
from heliostep.scenario.catalogue import load_catalogue

SCENARIO = scenarios_dir() / "jan21-central.yaml"
SETS = ["site.latitude=37", "window.duration=20"]
#: A refusal comes before any case is built: well under this even on a loaded machine [s].
QUICK = 5.0


def _catalogue(folder: Path) -> Path:
    path = folder / "motors.yaml"
    path.write_text(yaml.safe_dump({"motors": {"small": QSH8618_65_AT_3A}}), encoding="utf-8")
    return path


@pytest.fixture(scope="module")
def sized_at_37_north(tmp_path_factory, fmu_paths):
    folder = tmp_path_factory.mktemp("size37")
    catalogue, out = _catalogue(folder), folder / "out"
    argv = ["size", str(SCENARIO), "--catalogue", str(catalogue), "--days", "21", "--curve-rates", "5"]
    argv += ["--no-band-days", "--design-gust", "25", "--out", str(out)]
    for item in SETS:
        argv += ["--set", item]
    assert main(argv) == 0
    return catalogue, out


class _Page(HTMLParser):
    """The page's sections in order, each as the (tag, class, text) of its headings, paragraphs and cells."""

    def __init__(self):
        super().__init__()
        self.sections: list[list[tuple[str, str, str]]] = []
        self.style = ""
        self._open: list[tuple[str, str]] = []

    def handle_starttag(self, tag, attrs):
        if tag == "section":
            self.sections.append([])
        elif tag in ("h1", "h2", "p", "td", "style"):
            self._open.append((tag, dict(attrs).get("class") or ""))
            if tag != "style":
                self.sections[-1].append((tag, dict(attrs).get("class") or "", ""))

    def handle_endtag(self, tag):
        if self._open and self._open[-1][0] == tag:
            self._open.pop()

    def handle_data(self, data):
        if not self._open:
            return
        if self._open[-1][0] == "style":
            self.style += data
        else:
            tag, css, text = self.sections[-1][-1]
            self.sections[-1][-1] = (tag, css, text + data)


def test_the_inputs_block_is_the_resolved_scenario_with_every_set(sized_at_37_north):
    catalogue, out = sized_at_37_north
    sheet = json.loads((out / "sizing.json").read_text(encoding="utf-8"))
    inputs = sheet["inputs"]
    resolved = load_scenario(SCENARIO, SETS).resolved_dict()  # the oracle: the scenario loaded here
    assert inputs["site"] == resolved["site"] and inputs["site"]["latitude"] == 37.0
    assert inputs["window"] == {key: value for key, value in resolved["window"].items() if value is not None}
    assert inputs["transmission"] == resolved["transmission"]
    assert inputs["overrides"] == SETS
    assert inputs["scenario"] == {
        "name": "jan21-central",
        "file": str(SCENARIO),
        "sha256": hashlib.sha256(SCENARIO.read_bytes()).hexdigest(),
    }
    assert inputs["catalogue"] == {"file": str(catalogue), "sha256": hashlib.sha256(catalogue.read_bytes()).hexdigest()}
    assert inputs["days"]["days"][0]["day_of_year"] == 21 and inputs["days"]["kind"] == "given"
    assert inputs["mirror"]["aperture_area_m2"] == pytest.approx(0.45) and inputs["mirror"]["axis"] == "secondary"
    wind = inputs["wind"]
    assert wind["design_gust_m_s"] == 25.0 and wind["design_moment_Nm"] == sheet["wind"]["moment_Nm"]
    assert wind["peak_moment_coefficient"] == pytest.approx(0.1975, abs=5e-4)  # tests/drive/test_wind.py's peak
    assert wind["air_density_kg_m3"] == pytest.approx(1.225, rel=1e-6)  # ISA sea level
    assert inputs["safety_factor"] == sheet["safety_factor"] == 2.0
    versions = inputs["versions"]
    assert versions["heliostep"] == heliostep.__version__ and versions["python"] == platform.python_version()
    assert versions["packages"]["fmpy"] == metadata.version("fmpy")
    assert set(versions["packages"]) >= {"fmpy", "numpy", "pvlib", "pandas"}


def test_the_verdicts_fields_name_the_chosen_drive_and_its_governing_case(sized_at_37_north):
    _, out = sized_at_37_north
    sheet = json.loads((out / "sizing.json").read_text(encoding="utf-8"))
    verdict, row = sheet["verdict"], sheet["candidates"][0]["currents"][0]
    assert (verdict["candidate"], verdict["current_A"]) == ("small", 3.0)
    governing = verdict["governing"]
    least = min(
        [("tracking", row["tracking_margin"]), ("idle", row["idle_margin"]), ("stow", row["stow_margin"])],
        key=lambda item: item[1],
    )
    assert (governing["case"], governing["margin"]) == least
    assert verdict["next_smaller"] is None  # the catalogue has no smaller one
    assert verdict["text"].startswith("Chosen: small at 3 A. Governing case: ")
    assert "No smaller candidate was tried." in verdict["text"]


def test_the_page_opens_with_the_site_and_the_verdict_then_the_inputs(sized_at_37_north):
    _, out = sized_at_37_north
    sheet = json.loads((out / "sizing.json").read_text(encoding="utf-8"))
    page = _Page()
    page.feed((out / "sizing.html").read_text(encoding="utf-8"))
    first, inputs = page.sections[0], page.sections[1]
    (tag, _, title), (tag_2, css, paragraph) = first[0], first[1]
    assert tag == "h1" and "jan21-central at 37° N, 14.25° E, 0 m (Europe/Rome), with 2 --set" in title
    assert tag_2 == "p" and css == "verdict" and paragraph == sheet["verdict"]["text"]
    cells = [text for tag, _, text in inputs if tag == "td"]
    rows = dict(zip(cells[::2], cells[1::2]))
    assert inputs[0] == ("h2", "", "What it was sized for")
    assert rows["site latitude [deg N]"] == "37" and rows["design gust [m/s]"] == "25"
    assert [value for name, value in zip(cells[::2], cells[1::2]) if name == "--set [KEY=VALUE]"] == SETS
    assert rows["scenario file sha256 [hex]"] == hashlib.sha256(SCENARIO.read_bytes()).hexdigest()
    # printed, every section after the first starts a page of its own
    assert len(page.sections) >= 6
    assert "@media print{" in page.style and "section{break-before:page}" in page.style


def test_size_without_any_wind_is_exit_2_naming_the_options(tmp_path, capsys):
    catalogue, out = _catalogue(tmp_path), tmp_path / "out"
    started = time.perf_counter()
    status = main(["size", str(SCENARIO), "--catalogue", str(catalogue), "--days", "21", "--out", str(out)])
    took = time.perf_counter() - started
    message = capsys.readouterr().err
    assert status == 2 and took < QUICK
    assert f"{SCENARIO}: no wind to size against: expected --design-gust M_PER_S or a wind source" in message
    for key in ("wind.speed", "wind.weather_file", "wind.profile", "wind.moment"):
        assert key in message
    assert "Traceback" not in message and not out.exists()


def test_a_wind_moment_given_even_zero_is_the_wind_sized_against(tmp_path):
    from heliostep.sizing.size import plan_sizing

    candidates = load_catalogue(_catalogue(tmp_path))
    plan = plan_sizing(SCENARIO, candidates, days=[21], overrides=["wind.moment=0", "window.duration=20"])
    assert plan.wind_moment == 0.0 and plan.wind_source.endswith("wind.moment")
    assert plan.inputs["wind"]["moment_Nm"] == 0.0 and plan.inputs["wind"]["design_gust_m_s"] is None


def _least_margin(row: dict) -> tuple[str, float]:
    margins = {"tracking": row["tracking_margin"], "idle": row["idle_margin"], "stow": row["stow_margin"]}
    return min(margins.items(), key=lambda item: item[1])


def test_a_nema_17_fails_where_a_nema_23_passes_and_the_sheet_names_each_governing_case(tmp_path, fmu_paths):
    """The shipped catalogue's smallest NEMA 17 (0.27 N.m) and smallest NEMA 23 (1.01 N.m) against a 20 m/s
    design gust: the friction alone (0.08 N.m) leaves the NEMA 17 no margin of 2 at any current."""
    nema_17, nema_23 = "QSH4218-35-10-027", "QSH5718-51-28-101"
    frames = {c.name: c.frame for c in load_catalogue(None, [nema_17, nema_23])}
    assert frames == {nema_17: "NEMA 17", nema_23: "NEMA 23"}
    out = tmp_path / "out"
    argv = ["size", str(SCENARIO), "--candidate", nema_17, "--candidate", nema_23, "--days", "21"]
    argv += ["--curve-rates", "5", "--no-band-days", "--design-gust", "20", "--set", "window.duration=20"]
    assert main([*argv, "--out", str(out)]) == 0
    sheet = json.loads((out / "sizing.json").read_text(encoding="utf-8"))
    by_name = {c["name"]: c for c in sheet["candidates"]}
    assert by_name[nema_17]["verdict"] == "fail" and by_name[nema_23]["verdict"] == "pass"
    for entry in sheet["candidates"]:
        for row in entry["currents"]:
            assert (row["governing"]["case"], row["governing"]["margin"]) == _least_margin(row)
    verdict = sheet["verdict"]
    chosen = next(row for row in by_name[nema_23]["currents"] if row["verdict"] == "pass")
    assert (verdict["candidate"], verdict["current_A"]) == (nema_23, chosen["current_A"])
    assert verdict["governing"] == chosen["governing"]
    smaller = by_name[nema_17]["currents"][-1]  # the NEMA 17 at its highest current
    assert (
        verdict["next_smaller"]["candidate"] == nema_17 and verdict["next_smaller"]["governing"] == smaller["governing"]
    )
    case, margin = smaller["governing"]["case"], smaller["governing"]["margin"]
    assert (
        f"The next smaller candidate, {nema_17} at 1 A (its governing case {case}, margin {margin:.2f}), fails: "
        in (verdict["text"])
    )
    page = _Page()
    page.feed((out / "sizing.html").read_text(encoding="utf-8"))
    assert page.sections[0][1][2] == verdict["text"]
