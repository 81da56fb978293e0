"""Tests of ``heliostep geometry``: files, CSV columns, values from first principles, errors."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from heliostep.cli import main

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


@pytest.fixture
def paper_case_inputs():
    """The paper's Figs. 8-9: 21 January, 40 N, h = 3 m, d = 0, r = 2.5 mm, s = 0.3 m.

    The 12:00 start (Europe/Rome clock) is our documented choice, not the paper's.
    """
    return {"date": "2025-01-21", "start": "12:00", "pinion_radius": 2.5e-3, "lever_arm": 0.3}


@pytest.fixture(scope="module")
def run_output(tmp_path_factory):
    out = tmp_path_factory.mktemp("geometry") / "out"
    argv = [
        "geometry",
        "--out",
        str(out),
        "--date",
        "2025-12-21",
        "--date",
        "2025-06-21",
        "--step",
        "300",
        "--mirror",
        "0",
        "--mirror",
        "6",
        "--spacing",
        "0.5",
        "--paper-case",
        "--window-start",
        "12:00",  # near solar noon, for the half-zenith check below
        "--window-step",
        "10",
    ]
    status = main(argv)
    return status, out


def test_cli_writes_csvs_and_pngs(run_output):
    status, out = run_output
    assert status == 0
    for name in (
        "end_loss.png",
        "two_axis_angles.png",
        "paper_case_panel_angle.png",
        "paper_case_rotor_angle.png",
    ):
        assert (out / name).read_bytes()[:8] == PNG_MAGIC, name
    for name in ("end_loss.csv", "two_axis_angles.csv", "paper_case.csv"):
        assert (out / name).stat().st_size > 0, name


def test_cli_end_loss_csv_against_first_principles(run_output):
    _, out = run_output
    table = pd.read_csv(out / "end_loss.csv")
    assert {"time_local", "date", "mirror_distance_m", "apparent_elevation_deg", "azimuth_deg", "end_loss_m"} <= set(
        table.columns
    )
    assert set(table["date"]) == {"2025-12-21", "2025-06-21"}
    assert sorted(set(table["mirror_distance_m"])) == [-3.0, 0.0]  # mirror 0 at (0 - 6) * 0.5 m
    assert (table["apparent_elevation_deg"] > 0).all()
    central = table[(table["date"] == "2025-12-21") & (table["mirror_distance_m"] == 0.0)]
    noon = central.loc[central["apparent_elevation_deg"].idxmax()]
    # sun near due South at noon: k = h / tan(altitude), h = 5 m default, about 10 m (Fig. 2)
    assert noon["end_loss_m"] == pytest.approx(5.0 / np.tan(np.radians(noon["apparent_elevation_deg"])), rel=2e-3)
    assert noon["end_loss_m"] == pytest.approx(10.0, abs=0.3)
    assert str(noon["time_local"]).startswith("2025-12-21T12:")  # local (CET) clock times


def test_cli_two_axis_csv_against_first_principles(run_output):
    _, out = run_output
    table = pd.read_csv(out / "two_axis_angles.csv")
    for column in ("primary_deg", "secondary_deg", "primary_error_deg", "mirror_distance_m"):
        assert column in table.columns
    assert not table.isna().any().any()
    alt, az = np.radians(table["apparent_elevation_deg"]), np.radians(table["azimuth_deg"])
    sun = np.column_stack([np.cos(alt) * np.sin(az), np.cos(alt) * np.cos(az), np.sin(alt)])
    distance = table["mirror_distance_m"].to_numpy()
    target = np.column_stack([-distance, np.zeros_like(distance), np.full_like(distance, 5.0)])
    target /= np.linalg.norm(target, axis=1, keepdims=True)
    normal = (sun + target) / np.linalg.norm(sun + target, axis=1, keepdims=True)
    np.testing.assert_allclose(table["secondary_deg"], np.degrees(-np.arcsin(normal[:, 1])), atol=1e-8)
    np.testing.assert_allclose(table["primary_deg"], np.degrees(np.arctan2(normal[:, 0], normal[:, 2])), atol=1e-8)
    assert (table.loc[table["mirror_distance_m"] == 0.0, "primary_error_deg"] == 0.0).all()


def test_cli_paper_case_csv(run_output, paper_case_inputs):
    _, out = run_output
    table = pd.read_csv(out / "paper_case.csv")
    assert list(table["time_local"].iloc[[0, -1]]) == ["2025-01-21T12:00:00+0100", "2025-01-21T12:05:00+0100"]
    assert len(table) == 31  # 5 min at 10 s, both ends
    assert table["rotor_angle_ref_deg"].iloc[0] == 0.0
    panel = np.radians(table["panel_angle_ref_deg"])
    ratio = paper_case_inputs["lever_arm"] / paper_case_inputs["pinion_radius"]
    np.testing.assert_allclose(
        np.radians(table["rotor_angle_ref_deg"]), ratio * (np.tan(panel) - np.tan(panel.iloc[0])), atol=1e-12
    )
    # central mirror near noon: the normal bisects zenith and sun, so the secondary
    # is close to (90 - altitude) / 2 (the sun is ~4 deg east of South at 12:00)
    half_zenith = (90.0 - table["apparent_elevation_deg"]) / 2.0
    np.testing.assert_allclose(table["panel_angle_ref_deg"], half_zenith, atol=0.2)
    assert not table.isna().any().any()


@pytest.mark.parametrize(
    ("extra", "parameter"),
    [
        (["--latitude", "95"], "latitude"),
        (["--longitude", "-181"], "longitude"),
        (["--timezone", "Mars/Olympus_Mons"], "timezone"),
        (["--tube-height", "0"], "tube_height"),
        (["--orientation", "NE"], "orientation"),
        (["--date", "2025-13-01"], "--date"),
        (["--mirror", "13"], "--mirror"),
        (["--spacing", "-1", "--mirror", "3"], "spacing"),
        (["--paper-case", "--window-start", "noon"], "--window-start"),
        (["--paper-case", "--window-minutes", "0"], "--window-minutes"),
        (["--paper-case", "--pinion-radius", "0"], "--pinion-radius"),
        (["--paper-case", "--lever-arm", "-0.3"], "--lever-arm"),
        (["--paper-case", "--stow", "park"], "--stow"),
    ],
)
def test_cli_bad_option_exits_2_naming_the_parameter(extra, parameter, tmp_path, capsys):
    out = tmp_path / "out"
    status = main(["geometry", "--out", str(out), *extra])
    assert status == 2
    err = capsys.readouterr().err
    assert "heliostep geometry: error:" in err and parameter in err
    assert not out.exists()  # bad input is caught before anything is written
