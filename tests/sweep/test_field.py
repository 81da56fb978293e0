"""Tests of heliostep.sweep.field: the 13-mirror field with one shared primary drive.

The primary sharing errors are checked against the primary angles computed here from
first principles (pvlib's sun position, the mirror normal bisecting the sun and the
tube directions) and against :func:`heliostep.solar.two_axis_angles`.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import pvlib
import pytest

from heliostep.drive.inputs import reference_times
from heliostep.paths import scenarios_dir
from heliostep.scenario import load_scenario, validate_scenario
from heliostep.solar import two_axis_angles
from heliostep.sweep import expand_cases, field_sharing_errors, primary_sharing_error, run_field, sweep_from_scenario
from loopback_cluster import loopback_client
from receiver_tracer import trace

BASE = scenarios_dir() / "jan21-central.yaml"

SPACING = 0.6  # [m], the default of the field
DISTANCES = (np.arange(13) - 6) * SPACING  # [m], mirror index 0 .. 12


@pytest.fixture(scope="module")
def client(fmu_paths):
    with loopback_client() as dask_client:
        yield dask_client


def short_scenario(start: str = "10:00", duration: float = 20.0):
    return load_scenario(BASE, (f"window.start={start!r}", f"window.duration={duration}", "output.interval=0.5"))


def solar_noon_direction(scenario) -> np.ndarray:
    """Unit vector to the sun at solar noon of the window's date (pvlib SPA transit)."""
    site = scenario.site
    day = pd.DatetimeIndex([pd.Timestamp(scenario.window.date).tz_localize(site.timezone) + pd.Timedelta(hours=12)])
    transit = pvlib.solarposition.sun_rise_set_transit_spa(day, site.latitude, site.longitude)["transit"]
    sun = pvlib.solarposition.get_solarposition(
        pd.DatetimeIndex(transit), site.latitude, site.longitude, site.altitude, method="nrel_numpy"
    )
    elevation, azimuth = np.radians(sun["apparent_elevation"].iloc[0]), np.radians(sun["azimuth"].iloc[0])
    return np.array([np.cos(elevation) * np.sin(azimuth), np.cos(elevation) * np.cos(azimuth), np.sin(elevation)])


def sun_direction(scenario, seconds: float) -> np.ndarray:
    """Unit vector to the sun ``seconds`` after the window's start (pvlib SPA, apparent elevation)."""
    start, _ = scenario.window_bounds()
    site = scenario.site
    sun = pvlib.solarposition.get_solarposition(
        pd.DatetimeIndex([start + pd.Timedelta(seconds=seconds)]),
        site.latitude,
        site.longitude,
        site.altitude,
        method="nrel_numpy",
    )
    elevation, azimuth = np.radians(sun["apparent_elevation"].iloc[0]), np.radians(sun["azimuth"].iloc[0])
    return np.array([np.cos(elevation) * np.sin(azimuth), np.cos(elevation) * np.cos(azimuth), np.sin(elevation)])


def primary_at(to_sun: np.ndarray, distance: float, height: float) -> float:
    """Primary angle of a two-axis mirror at ``distance`` for one sun direction (normal bisects sun and tube)."""
    normal = to_sun + np.array([-distance, 0.0, height]) / np.hypot(distance, height)
    return float(np.arctan2(normal[0], normal[2]))


def first_principles_errors(scenario) -> dict[float, tuple[float, float]]:
    """mirror distance -> (max |primary error| [deg], signed error at that instant [deg])."""
    start, end = scenario.window_bounds()
    times = start + pd.to_timedelta(reference_times((end - start).total_seconds()), unit="s")
    site = scenario.site
    sun = pvlib.solarposition.get_solarposition(
        times, site.latitude, site.longitude, site.altitude, method="nrel_numpy"
    )
    elevation = np.radians(sun["apparent_elevation"].to_numpy())
    azimuth = np.radians(sun["azimuth"].to_numpy())
    # North-South plant: x = East, y = North, z = up; the tube over x = 0 at height h
    to_sun = np.stack(
        [np.cos(elevation) * np.sin(azimuth), np.cos(elevation) * np.cos(azimuth), np.sin(elevation)], axis=1
    )
    height = scenario.plant.tube_height

    def primary(distance):
        to_tube = np.array([-distance, 0.0, height]) / np.hypot(distance, height)
        normal = to_sun + to_tube  # bisects the sun and tube directions
        return np.arctan2(normal[:, 0], normal[:, 2])

    central = primary(0.0)
    # the mirrors are mounted exact at solar noon: the offsets are the differences there
    noon = solar_noon_direction(scenario)
    errors = {}
    for distance in DISTANCES:
        offset = primary_at(noon, distance, height) - primary_at(noon, 0.0, height)
        error = np.degrees(primary(distance) - central - offset)
        library, _ = two_axis_angles(sun["apparent_elevation"].to_numpy(), sun["azimuth"].to_numpy(), distance, height)
        library_central, _ = two_axis_angles(
            sun["apparent_elevation"].to_numpy(), sun["azimuth"].to_numpy(), 0.0, height
        )
        np.testing.assert_allclose(np.radians(error) + offset, library - library_central, rtol=0, atol=1e-12)
        worst = int(np.argmax(np.abs(error)))
        errors[float(distance)] = (abs(error[worst]), error[worst])
    return errors


def test_field_run_reports_sharing_error_beside_secondary_error(client, tmp_path):
    scenario = short_scenario()
    table = run_field(scenario, tmp_path / "results.parquet", client=client)
    assert len(table) == 14 and (table["status"] == "ok").all()
    mirrors = table[table["role"] == "drive"].set_index("mirror_index")
    assert list(mirrors.index) == list(range(13))
    assert (mirrors["mirror_axis"] == "secondary").all()
    np.testing.assert_allclose(mirrors["mirror_distance_m"], DISTANCES, atol=1e-12)
    assert (mirrors["max_tracking_error_deg"] > 0).all() and mirrors["peak_phase_current_A"].notna().all()
    shared = table[table["role"] == "shared-primary"]
    assert len(shared) == 1 and shared["mirror_axis"].item() == "primary" and shared["mirror_index"].item() == 6

    expected = first_principles_errors(scenario)
    assert mirrors.loc[6, "primary_sharing_error_max_deg"] == 0.0
    for index in range(13):
        magnitude, signed = expected[float(DISTANCES[index])]
        assert mirrors.loc[index, "primary_sharing_error_max_deg"] == pytest.approx(magnitude, rel=1e-9, abs=1e-12)
        assert mirrors.loc[index, "primary_sharing_error_signed_deg"] == pytest.approx(signed, rel=1e-9, abs=1e-12)

    # light on the tube with the shared primary, beside each mirror's own figures
    optics = scenario.optics
    assert mirrors.loc[6, "light_lost_shared_primary_J"] == pytest.approx(
        0.0, abs=1e-6 * mirrors.loc[6, "light_energy_ideal_J"]
    )  # the central law is the central mirror's own
    height = scenario.plant.tube_height
    to_sun = sun_direction(scenario, 10.0)  # mid-window: the error moves < 0.01 deg in 20 s
    for index in range(13):
        row, distance = mirrors.loc[index], DISTANCES[index]
        # no "actual <= ideal": a finite mirror's image is wider than the tube, and aiming the central
        # ray at the own cross-section is not the energy optimum (issue #20), so the shared primary's
        # small offset can gain a little; the intercept itself is checked against the ray tracer below
        assert row["light_energy_ideal_J"] > 0 and row["light_energy_J"] > 0
        # the mirror's own normal bisects sun and tube; the shared motor turns it by -delta about y
        to_tube = np.array([-distance, 0.0, height]) / np.hypot(distance, height)
        own = (to_sun + to_tube) / np.linalg.norm(to_sun + to_tube)
        delta = -np.radians(expected[float(distance)][1])
        normal = np.array(
            [own[0] * np.cos(delta) + own[2] * np.sin(delta), own[1], -own[0] * np.sin(delta) + own[2] * np.cos(delta)]
        )
        # the finite 0.3 m x 1.5 m flat mirror over the bare 70 mm tube, traced (tests/support/receiver_tracer.py)
        gamma, error = trace(
            to_sun,
            np.arctan2(normal[0], normal[2]),
            -np.arcsin(normal[1]),
            distance,
            height,
            optics.mirror_width,
            optics.mirror_length,
            optics.tube_diameter,
            optics.focal_length,
            optics.slope_error,
            optics.specularity,
            rays=100_000,
        )
        assert row["mean_intercept"] == pytest.approx(gamma, abs=0.02 + 3 * error), index
    assert mirrors.loc[0, "mean_intercept"] < 0.01  # the outer West mirror's light misses the tube


def test_sharing_errors_vanish_at_solar_noon_where_the_mirrors_are_mounted():
    noon = pvlib.solarposition.sun_rise_set_transit_spa(
        pd.DatetimeIndex([pd.Timestamp("2025-01-21 12:00", tz="Europe/Rome")]), 40.0, 14.25
    )["transit"].iloc[0]
    start = (pd.Timestamp(noon).tz_convert("Europe/Rome") - pd.Timedelta(seconds=1)).floor("s")
    errors = field_sharing_errors(short_scenario(start.strftime("%H:%M:%S"), duration=2.0))
    # within 2 s of noon the sun moves by ~0.008 deg: the motion errors are a small fraction of that
    assert errors["primary_sharing_error_max_deg"].max() < 1e-3
    assert errors.loc[6, "primary_sharing_error_max_deg"] == 0.0


def test_field_sharing_errors_match_the_per_case_figure_and_first_principles():
    scenario = short_scenario()
    errors = field_sharing_errors(scenario, [0, 6, 9])
    expected = first_principles_errors(scenario)
    for index in (0, 6, 9):
        assert errors.loc[index, "primary_sharing_error_max_deg"] == pytest.approx(
            expected[float(DISTANCES[index])][0], rel=1e-9, abs=1e-12
        )
    single = primary_sharing_error(load_scenario(BASE, ("window.duration=20", "mirror.distance=-3.6")))
    assert single["primary_sharing_error_max_deg"] == pytest.approx(errors.loc[0, "primary_sharing_error_max_deg"])
    night = primary_sharing_error(short_scenario("23:00"))
    assert night == {"primary_sharing_error_max_deg": None, "primary_sharing_error_signed_deg": None}


def test_mirror_all_shorthand_sweeps_the_field():
    spec = sweep_from_scenario(short_scenario(), {"mirror": "all"}, shared_primary=True)
    cases = expand_cases(spec)
    assert [c.columns["mirror_index"] for c in cases] == [*range(13), 6]
    assert [c.columns["role"] for c in cases] == ["drive"] * 13 + ["shared-primary"]


def test_shared_primary_case_carries_the_fields_panels_about_their_longitudinal_axes():
    # Table 2: M = 18 kg, rho = 800 kg/m3, l = 1.5 m, sp = 0.05 m -> width w = M/(rho l sp) = 0.3 m;
    # 13 panels each M/12 (w^2 + sp^2) about the longitudinal axis; the rack at the panel edge, w/2
    width = 18.0 / (800.0 * 1.5 * 0.05)
    inertia = 13 * 18.0 / 12.0 * (width**2 + 0.05**2)
    assert width == pytest.approx(0.3) and inertia == pytest.approx(1.80375)
    spec = sweep_from_scenario(load_scenario(BASE), {"mirror": [0, 6]}, shared_primary=True)
    cases = expand_cases(spec)
    primary = [case for case in cases if case.columns["role"] == "shared-primary"]
    drives = [case for case in cases if case.columns["role"] == "drive"]
    assert len(primary) == 1 and len(drives) == 2
    scenario = primary[0].scenario
    assert scenario["mirror"]["axis"] == "primary"
    assert scenario["parameters"]["mechanics"]["J_p"] == pytest.approx(inertia)
    assert scenario["transmission"]["lever_arm"] == pytest.approx(width / 2)
    for case in drives:  # the secondaries keep the panel of Table 2 about the secondary axis
        assert "J_p" not in case.scenario["parameters"].get("mechanics", {})
        assert case.scenario["transmission"]["lever_arm"] == pytest.approx(0.3)


def test_shorthand_motor_axis_swaps_the_instance_that_plays_the_motor(tmp_path):
    # instances renamed: the 'motor' axis follows the torque role, not the name 'motor'
    renamed = load_scenario(
        BASE,
        [
            "fmus.motor=null",
            "fmus.mechanics=null",
            "fmus.coil=StepperMotor",
            "fmus.panel=PanelMechanics",
            "connections=[[coil.tau, panel.tau], [panel.theta, coil.theta], [panel.omega, coil.omega]]",
            "roles={current_a_ref: coil.i_a_ref, current_b_ref: coil.i_b_ref, "
            "torque: coil.tau, rotor_angle: panel.theta, panel_angle: panel.theta_p}",
        ],
    )
    spec = sweep_from_scenario(renamed, {"motor": ["StepperMotor", "StepperMotorIdealCurrent"]})
    cases = expand_cases(spec)
    assert [case.scenario["fmus"]["coil"] for case in cases] == ["StepperMotor", "StepperMotorIdealCurrent"]
    for case in cases:  # the dropped default instances stay dropped when a worker reads the case back
        assert case.scenario["fmus"].get("motor") is None
        assert set(validate_scenario(case.scenario, folder=case.folder).fmus) == {"coil", "panel"}
    assert [case.columns["motor"] for case in cases] == ["StepperMotor", "StepperMotorIdealCurrent"]
