"""``heliostep run`` with bad optics or weather input: exit 2 before simulating, naming the file and key."""

from __future__ import annotations

import json

import pytest

from heliostep import cli
from heliostep.paths import scenarios_dir
from weather_files import write_epw

SCENARIO = scenarios_dir() / "jan21-central.yaml"  # 40 N, 14.25 E, 21 January 10:00, Europe/Rome


def _run(tmp_path, capsys, *overrides):
    argv = ["run", str(SCENARIO), "--out", str(tmp_path / "out"), "--no-plots"]
    for item in overrides:
        argv += ["--set", item]
    status = cli.main(argv)
    return status, capsys.readouterr().err


@pytest.mark.parametrize(
    "key, value",
    [
        ("mirror_area", -1.5),
        ("tube_diameter", -0.07),
        ("reflectivity", 1.2),
        ("transmittance", -0.1),
        ("absorptance", 2),
    ],
)
def test_bad_optics_value_is_exit_2_naming_the_file_and_key(tmp_path, capsys, key, value):
    status, err = _run(tmp_path, capsys, f"optics.{key}={value}")
    assert status == 2
    assert SCENARIO.name in err and f"optics.{key}" in err
    assert not (tmp_path / "out").exists()  # found before anything was written


@pytest.mark.parametrize(
    "make, expected",
    [
        (lambda p: p.write_text("not a weather file\n") and p, "cannot read"),
        (lambda p: write_epw(p, latitude=48.0, longitude=14.25), "latitude 48"),  # another site
        (lambda p: write_epw(p, latitude=40.0, longitude=14.25, month=6, day=21), "does not cover the window"),
    ],
)
def test_bad_weather_file_is_exit_2_naming_the_file_and_key(tmp_path, capsys, make, expected):
    path = tmp_path / "site.epw"
    make(path)
    status, err = _run(tmp_path, capsys, f"optics.weather_file={path}")
    assert status == 2
    assert SCENARIO.name in err and "optics.weather_file" in err and str(path) in err and expected in err
    assert not (tmp_path / "out" / "trace.parquet").exists()


def test_missing_weather_file_is_exit_2(tmp_path, capsys):
    status, err = _run(tmp_path, capsys, f"optics.weather_file={tmp_path / 'nowhere.epw'}")
    assert status == 2 and "optics.weather_file" in err and "nowhere.epw" in err


def test_weather_file_for_the_site_and_window_runs(tmp_path, capsys, fmu_paths):
    path = write_epw(tmp_path / "site.epw", latitude=40.0, longitude=14.25, dni_of_hour=lambda h: 700.0)
    status, _ = _run(tmp_path, capsys, f"optics.weather_file={path}", "window.duration=20", "output.interval=0.5")
    assert status == 0
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert summary["dni_source"] == str(path)
    # 700 W/m^2 all hour, 0.3 m x 1.5 m, rho tau alpha = 0.646: at most 203 W absorbed, 4.07 kJ in 20 s;
    # the flat mirror's image over the 70 mm tube takes about a quarter of it (ray traced in
    # tests/solar/test_raytrace.py: 0.24 at 10:00), times a cosine near 0.9
    assert 0.15 * 4.07e3 < summary["light_energy_ideal_J"] < 0.35 * 4.07e3
