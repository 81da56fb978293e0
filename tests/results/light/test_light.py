"""Tests of heliostep.results.light.on_tube: energy on the tube against an independent computation."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from pvlib.location import Location
from scipy.special import erf

from heliostep.errors import InputError
from heliostep.results.light.notes import INTERPOLATION_NOISE
from heliostep.results.light.on_tube import LightIntegrals, light_figures, light_notes, light_timeseries
from heliostep.scenario import validate_scenario
from heliostep.solar.tracking import panel_angle_reference

#: Sun's pillbox half-angle 4.65 mrad -> 1-D sigma 4.65/2 mrad (Rabl, Active Solar Collectors, 1985).
SUN_SIGMA = 4.65e-3 / 2
PANEL_COLUMN = "mechanics.theta_p"
#: A point mirror of 1.5 m^2 with no slope error: the intercept is then the sun's Gaussian on the tube
#: (erf, written below); the finite mirror's image is checked against a ray tracer
#: (tests/solar/test_raytrace.py and test_finite_mirror_intercept_is_the_ray_traced_one here).
POINT = {"mirror_width": 1e-6, "mirror_length": 1e-6, "mirror_area": 1.5, "slope_error": 0.0}


def _scenario(distance=0.0, axis="secondary", **optics):
    return validate_scenario(
        {
            "name": "light-test",
            "site": {"latitude": 40.0, "longitude": 14.25, "altitude": 0.0, "timezone": "Europe/Rome"},
            "window": {"date": "2025-01-21", "start": "10:00", "duration": 1800},
            "plant": {"orientation": "NS", "tube_height": 3.0},
            "mirror": {"distance": distance, "axis": axis},
            **({"optics": optics} if optics else {}),
        }
    )


def _trace(scenario, offset=0.0, step=1.0):
    start = pd.Timestamp("2025-01-21 10:00", tz="Europe/Rome")
    seconds = np.arange(0.0, 1800.0 + step, step)
    times = start + pd.to_timedelta(seconds, unit="s")
    site, plant = scenario.site.to_site(), scenario.plant.to_plant()
    ref = panel_angle_reference(times, site, plant, scenario.mirror.mirror_distance, axis=scenario.mirror.axis)
    trace = pd.DataFrame({"time": seconds, "panel_angle_ref": ref.to_numpy(), PANEL_COLUMN: ref.to_numpy() + offset})
    metadata = {"window_start": start.isoformat(), "timezone": "Europe/Rome", "roles": {"panel_angle": PANEL_COLUMN}}
    return trace, metadata, times


@pytest.mark.filterwarnings("ignore::Warning")
@pytest.mark.parametrize("distance", [0.0, 2.4])
def test_ideal_energy_equals_dni_area_cosine_chain_integrated(distance):
    scenario = _scenario(distance, **POINT)
    trace, metadata, times = _trace(scenario)
    figures = light_figures(trace, metadata, scenario)
    # independent: pvlib clear sky and sun position, the cosine of half the angle between S and T
    location = Location(40.0, 14.25, "Europe/Rome", 0.0)
    dni = location.get_clearsky(times, model="ineichen")["dni"].to_numpy()
    sun = location.get_solarposition(times)
    alt, az = np.radians(sun["apparent_elevation"].to_numpy()), np.radians(sun["azimuth"].to_numpy())
    s = np.stack([np.cos(alt) * np.sin(az), np.cos(alt) * np.cos(az), np.sin(alt)])
    slant = np.hypot(distance, 3.0)
    t = np.array([-distance, 0.0, 3.0]) / slant
    cosine = np.sqrt((1.0 + t @ s) / 2.0)  # the normal bisects S and T
    o = scenario.optics
    sigma = np.sqrt(SUN_SIGMA**2 + (2 * o.slope_error) ** 2 + o.specularity**2)
    gamma = erf(o.tube_diameter / 2 / (np.sqrt(2) * slant * sigma))
    expected = np.trapezoid(dni * o.aperture_area * cosine * 0.80 * 0.85 * 0.95 * gamma, trace["time"].to_numpy())
    assert figures["light_energy_ideal_J"] == pytest.approx(expected, rel=1e-5)
    assert figures["light_lost_stepping_J"] == pytest.approx(0.0, abs=1e-6 * expected)  # the trace tracks exactly
    if distance == 0.0:  # the central mirror's primary is its own: no sharing loss
        assert figures["light_energy_J"] == pytest.approx(expected, rel=1e-5)


def test_shared_primary_costs_light_off_centre():
    central = light_figures(*_trace(_scenario(0.0))[:2], _scenario(0.0))
    # the central mirror's primary is the shared one: its sharing error is 0 by definition, so
    # the loss is exactly 0 (it was -1e-3 J of interpolation noise when taken as ideal - reference)
    assert central["light_lost_shared_primary_J"] == 0.0
    assert any("exactly 0" in note for note in central["light_notes"])
    assert any("neighbouring mirrors are not" in note for note in central["light_notes"])
    outer = _scenario(6.0)
    figures = light_figures(*_trace(outer)[:2], outer)
    assert figures["light_lost_shared_primary_J"] > 0.01 * figures["light_energy_ideal_J"]
    for f in (central, figures):  # the three parts make up ideal - actual
        parts = f["light_lost_shared_primary_J"] + f["light_lost_reference_law_J"] + f["light_lost_stepping_J"]
        assert parts == pytest.approx(f["light_lost_J"], abs=1e-9 * f["light_energy_ideal_J"])
    primary = _scenario(0.0, axis="primary")
    assert light_figures(*_trace(primary)[:2], primary)["light_lost_shared_primary_J"] == 0.0


def test_reference_law_noise_is_flagged_not_meaningful():
    # the trace's reference is the exact law at the rows, the ideal interpolated from a 10 s sun
    # grid: their difference is (omega dt)^2/8 ~ 7e-8 rad of angle, far below 1e-6 of the energy
    scenario = _scenario(0.0)
    figures = light_figures(*_trace(scenario)[:2], scenario)
    assert abs(figures["light_lost_reference_law_J"]) < 1e-6 * figures["light_energy_reference_J"]
    assert any(
        note.startswith("light_lost_reference_law_J") and "not meaningful" in note for note in figures["light_notes"]
    )


def test_primary_offset_loses_light_as_the_intercept_says():
    scenario = _scenario(0.0, axis="primary", **POINT)
    delta = 4e-3  # [rad]: the ray turns by 2 delta in the cross-section, the miss is h sin(2 delta)
    trace, metadata, _ = _trace(scenario, offset=delta)
    series = light_timeseries(trace, metadata, scenario)
    miss = series["transverse_miss_actual_m"].to_numpy()
    assert np.all(
        np.abs(miss) > 0.5 * 3.0 * np.sin(2 * delta)
    )  # about h sin(2 delta) (exact with the sun in the plane)
    half = scenario.optics.tube_diameter / 2
    spread = np.sqrt(2) * 3.0 * SUN_SIGMA  # slant = h at d = 0, miss << h
    ratio = 0.5 * (erf((half - miss) / spread) + erf((half + miss) / spread)) / erf(half / spread)
    ratio *= series["cosine_actual"] / series["cosine_reference"]
    np.testing.assert_allclose(series["power_actual_W"], ratio * series["power_reference_W"], rtol=1e-3)
    figures = light_figures(trace, metadata, scenario)
    assert figures["light_lost_stepping_J"] > 0.005 * figures["light_energy_reference_J"]


@pytest.mark.parametrize("distance", [0.0, 2.4])
def test_secondary_stepping_changes_the_light_by_its_first_order_term(distance):
    """A secondary offset +-delta changes the light by its first-order term, of the offset's sign.

    The change dE(delta) = a delta + b delta^2 + O(delta^3): its odd part (dE(+delta) - dE(-delta)) / 2
    is the first-order term (to O(delta^3)), and doubling delta doubles the odd part and
    quadruples the even part. At d = 0 it is all the cosine's for a point mirror (its image centred
    on the tube, where the intercept is flat); a finite two-axis mirror's sheared image is not."""
    scenario = _scenario(distance, **POINT)
    delta = np.radians(0.006)  # the measured stepping error of the secondary
    change = {}
    for k in (1, -1, 2, -2):
        change[k] = light_figures(*_trace(scenario, offset=k * delta)[:2], scenario)
    dE = {k: f["light_stepping_change_J"] for k, f in change.items()}
    odd, even = 0.5 * (dE[1] - dE[-1]), 0.5 * (dE[1] + dE[-1])
    assert change[1]["light_stepping_first_order_J"] == pytest.approx(odd, rel=1e-4)
    assert change[-1]["light_stepping_first_order_J"] == pytest.approx(-odd, rel=1e-4)
    assert 0.5 * (dE[2] - dE[-2]) == pytest.approx(2 * odd, rel=1e-3)
    assert 0.5 * (dE[2] + dE[-2]) == pytest.approx(4 * even, rel=0.02)
    assert np.sign(dE[1]) == -np.sign(dE[-1]) != 0  # the sign follows the mean error's
    assert change[1]["light_stepping_mean_error_rad"] == pytest.approx(delta, rel=1e-9)
    assert change[1]["light_lost_stepping_J"] == -dE[1]  # the old key, its negative
    assert any("not a loss" in note and "first order" in note for note in change[1]["light_notes"])
    if distance == 0.0:
        cosine = change[1]["light_stepping_first_order_cosine_J"]
        assert cosine == pytest.approx(change[1]["light_stepping_first_order_J"], rel=1e-3)


def test_without_the_first_order_terms_every_other_light_figure_is_the_same_bit_for_bit():
    # a sweep's case leaves out the two attitudes of the first-order terms (its table does not hold them)
    scenario = _scenario(2.4)
    trace, metadata, _ = _trace(scenario, offset=np.radians(0.006))
    figures = {}
    for first_order in (True, False):
        integrals = LightIntegrals(metadata, scenario, first_order=first_order)
        for start in range(0, len(trace), 700):  # in blocks, as a run feeds them
            integrals(trace.iloc[start : start + 700])
        figures[first_order] = integrals.figures()
    left_out = {"light_stepping_first_order_J", "light_stepping_first_order_cosine_J", "light_stepping_mean_error_rad"}
    assert figures[True].keys() == figures[False].keys()
    for key in left_out:
        assert figures[False][key] is None and figures[True][key] != 0.0
    for key in figures[True].keys() - left_out - {"light_notes"}:
        assert figures[False][key] == figures[True][key], key
    assert figures[True]["light_energy_J"] != figures[True]["light_energy_reference_J"]  # the offset counts
    assert any("not computed" in note for note in figures[False]["light_notes"])


def _stepped_run(scenario):
    """A stepped trace of ``scenario`` (0.006 deg steps every 60 s about the reference), with a stowed
    span and the step times in its metadata, and a solution's swing (``error_extremes_deg``)."""
    trace, metadata, _ = _trace(scenario)
    held = trace["panel_angle_ref"].to_numpy()[(trace["time"].to_numpy() // 60.0 * 60.0).astype(int)]
    trace[PANEL_COLUMN] = held + np.radians(0.006)
    drive = {"step_times": list(np.arange(60.0, 1800.0, 60.0)), "stowed_spans_s": [[1500.0, 1600.0]]}
    swing = [[t, 0.01, held[int(t)] + 1e-3] for t in (630.0, 1230.0)]
    return trace, {**metadata, "drive": drive}, {"error_extremes_deg": swing}


@pytest.mark.parametrize("axis", ["secondary", "primary"])
def test_each_figure_asked_for_alone_is_the_same_bit_for_bit_as_among_all(axis):
    """``wanted`` (a sweep asking for ``light_energy_J`` alone): each figure computed alone, its attitudes'
    light alone at the rows (FIGURE_NEEDS), is the one computed with every figure, bit for bit; and
    ``light_energy_J`` alone takes the actual attitude's light alone at the trace's rows."""
    from heliostep.results.light import on_tube

    scenario = _scenario(2.4, axis=axis)
    trace, metadata, solution = _stepped_run(scenario)

    def figures(wanted=None):
        integrals = LightIntegrals(metadata, scenario, wanted=wanted)
        for start in range(0, len(trace), 700):  # in blocks, as a run feeds them
            integrals(trace.iloc[start : start + 700])
        return integrals.figures(solution)

    every = figures()
    assert every.keys() == on_tube.FIGURE_NEEDS.keys()
    assert every["light_lost_stowed_J"] != 0 and every["max_transverse_miss_m"] > 0
    for name in every:
        assert figures([name]) == {name: every[name]}, name
    assert figures(["light_energy_J", "mean_intercept"]) == {k: every[k] for k in ("light_energy_J", "mean_intercept")}
    rows = []
    original = on_tube.attitude_light

    def counting(sun, *args, **kwargs):
        rows.append(sun.shape[1])
        return original(sun, *args, **kwargs)

    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(on_tube, "attitude_light", counting)
        figures(["light_energy_J"])
        # the actual attitude's alone: at each of the three blocks' rows, and turned by +-COSINE_STEP at the
        # first row and each step's (their slopes, :mod:`heliostep.results.light.rows`)
        assert len(rows) == 3 + 3 and sum(rows) == len(trace) + 3 * (1 + 29)
        rows.clear()
        figures()
        # every attitude's (no shared one for a driven primary), the first order's two, the turned rows;
        # and the ideal and actual at the swing
        assert len(rows) == 3 * (6 if axis == "primary" else 7) + 2


def test_an_unknown_light_figure_is_an_error_naming_it():
    with pytest.raises(ValueError, match="light_energy_W"):
        LightIntegrals({}, _scenario(), wanted=["light_energy_J", "light_energy_W"])


def test_secondary_stepping_error_moves_light_along_the_tube():
    scenario = _scenario(0.0)
    delta = np.radians(0.006)  # the measured stepping error of the secondary
    figures = light_figures(*_trace(scenario, offset=delta)[:2], scenario)
    # an infinite tube keeps light shifted along it: only the cosine changes, to first order in delta
    assert abs(figures["light_lost_stepping_fraction"]) < 1e-3
    assert figures["max_longitudinal_miss_m"] == pytest.approx(3.0 * np.tan(2 * delta), rel=0.05)


@pytest.mark.parametrize(
    "key, value", [("mirror_area", -1.0), ("tube_diameter", 0.0), ("reflectivity", 1.2), ("absorptance", -0.1)]
)
def test_bad_optics_are_errors_naming_the_key(key, value):
    with pytest.raises(InputError, match=key):
        _scenario(**{key: value})


@pytest.mark.parametrize(
    "key, value",
    [
        ("mirror_width", -0.3),
        ("focal_length", 0.0),
        ("focal_length", -3.0),
        ("secondary", {"aperture_width": 0.3, "acceptance_half_angle": 0.0, "reflectivity": 0.9}),
        ("secondary", {"aperture_width": 0.3, "acceptance_half_angle": 90.0, "reflectivity": 0.9}),
        ("secondary", {"aperture_width": 0.3, "acceptance_half_angle": 45.0, "reflectivity": 0.0}),
        ("secondary", {"aperture_width": 0.3, "acceptance_half_angle": 45.0, "reflectivity": 1.1}),
        ("secondary", {"aperture_width": -0.3, "acceptance_half_angle": 45.0, "reflectivity": 0.9}),
    ],
)
def test_bad_mirror_and_secondary_are_errors_naming_the_key(key, value):
    with pytest.raises(InputError, match=key):
        _scenario(**{key: value})


@pytest.mark.filterwarnings("ignore::Warning")
def test_finite_mirror_intercept_is_the_ray_traced_one():
    """The default mirror (flat, 0.3 m x 1.5 m, bare 70 mm tube) at the paper's instant: the light
    series' intercept against the ray tracer (tests/support/receiver_tracer.py), and the area w x l."""
    from receiver_tracer import trace

    scenario = _scenario(0.0)
    assert scenario.optics.aperture_area == pytest.approx(0.3 * 1.5)
    trace_frame, metadata, times = _trace(scenario, step=300.0)
    series = light_timeseries(trace_frame, metadata, scenario)
    location = Location(40.0, 14.25, "Europe/Rome", 0.0)
    sun = location.get_solarposition(times)
    alt, az = np.radians(sun["apparent_elevation"].to_numpy()), np.radians(sun["azimuth"].to_numpy())
    for k in range(len(times)):
        s = np.array([np.cos(alt[k]) * np.sin(az[k]), np.cos(alt[k]) * np.cos(az[k]), np.sin(alt[k])])
        normal = (s + np.array([0.0, 0.0, 1.0])) / np.linalg.norm(s + np.array([0.0, 0.0, 1.0]))
        o = scenario.optics
        gamma, error = trace(
            s, np.arctan2(normal[0], normal[2]), -np.arcsin(normal[1]), 0.0, 3.0, 0.3, 1.5, 0.07, None,
            o.slope_error, 0.0, rays=200_000,
        )  # fmt: skip
        assert series["intercept_ideal"].iloc[k] == pytest.approx(gamma, abs=0.02 + 3 * error)


def test_unknown_optics_key_is_an_error():
    with pytest.raises(InputError, match="colour"):
        _scenario(colour="silver")


def test_end_effect_cuts_the_light_that_lands_past_the_tubes_end():
    # a 1.5 m mirror centred 0.5 m before the tube's end: its ideal light lands in its own
    # cross-section (no longitudinal shift), so 1.25 m of its 1.5 m length lights the tube
    open_tube = _scenario(0.0)
    at_end = _scenario(0.0, tube_ends=[-50.0, 0.5])
    trace, metadata, _ = _trace(at_end)
    ratio = (
        light_figures(trace, metadata, at_end)["light_energy_ideal_J"]
        / light_figures(trace, metadata, open_tube)["light_energy_ideal_J"]
    )
    assert ratio == pytest.approx(1.25 / 1.5, rel=1e-6)  # (the sun interpolated onto the rows: um shifts)
    # a secondary error delta shifts the light by k along the tube: (0.5 + 0.75 - k) / 1.5 of it lands on it
    delta = 0.01  # [rad]
    series = light_timeseries(*_trace(at_end, offset=delta)[:2], at_end)
    shift = series["longitudinal_miss_actual_m"].to_numpy()
    assert np.all(np.abs(shift) > 0.5 * 3.0 * np.tan(2 * delta))  # about h tan(2 delta), tens of mm
    np.testing.assert_allclose(series["end_fraction_actual"], np.clip(1.25 - shift, 0.0, 1.5) / 1.5, rtol=1e-12)


def test_tube_ends_out_of_order_is_an_error_naming_the_key():
    with pytest.raises(InputError, match="tube_ends"):
        _scenario(tube_ends=[1.0, -1.0])


def test_the_mean_stepping_error_is_a_time_average_not_a_row_average():
    # rows cluster where the drive steps: +delta over the first 900 s in 0.25 s rows, -delta over
    # the last 900 s in 5 s rows; weighted by the (near constant) power over time the mean is ~0
    scenario = _scenario(0.0)
    trace, metadata, _ = _trace(scenario, step=0.25)
    keep = (trace["time"] < 900.0) | (trace["time"] % 5.0 == 0.0)
    trace = trace[keep].reset_index(drop=True)
    delta = 1e-4  # [rad]
    trace[PANEL_COLUMN] = trace["panel_angle_ref"] + np.where(trace["time"] < 900.0, delta, -delta)
    figures = light_figures(trace, metadata, scenario)
    rows = np.where(trace["time"] < 900.0, delta, -delta).mean()  # +0.9 delta: the rows' mean
    assert rows > 0.8 * delta
    # weighted by the power in time: +delta and -delta each over 900 s, the power rising near
    # linearly from P0 to P1 (7 % over the window), so the mean is delta (P1bar - P2bar) / (P1bar + P2bar)
    # with the halves' means P0 + (P1 - P0)/4 and P0 + 3 (P1 - P0)/4; the step at 900 s is spread
    # over one 5 s row (5 / 1800 of the window): tolerance 0.005 delta
    power = light_timeseries(trace, metadata, scenario)["power_reference_W"].to_numpy()
    first, second = power[0] + (power[-1] - power[0]) / 4, power[0] + 3 * (power[-1] - power[0]) / 4
    expected = delta * (first - second) / (first + second)
    assert figures["light_stepping_mean_error_rad"] == pytest.approx(expected, abs=0.005 * delta)


def test_a_mirror_that_gets_no_light_has_figures_and_notes():
    # a point mirror at the outer West place with the shared primary misses the tube at 10:00: its
    # reference light is the sun's Gaussian tail only; the figures and their notes still come out
    scenario = _scenario(-3.6, **POINT)
    figures = light_figures(*_trace(scenario, offset=1e-4)[:2], scenario)
    assert figures["light_energy_reference_J"] < 1e-6 * figures["light_energy_ideal_J"]
    assert any("not a loss" in note for note in figures["light_notes"])
    # with no reference light at all there is no mean error to weight: the note says so
    dark = {**figures, "light_energy_reference_J": 0.0, "light_stepping_mean_error_rad": None}
    assert any("none: no light" in note for note in light_notes(dark, "secondary", -3.6))


@pytest.mark.parametrize(
    "optics",
    [
        {},  # a bare tube running on past the mirror
        # a secondary concentrator (its acceptance near the central ray's 38.7 deg from the vertical)
        # and the tube's start 0.4 m past the mirror's centre: the end fraction from the interpolated miss
        {
            "secondary": {"aperture_width": 0.2, "acceptance_half_angle": 40.0, "reflectivity": 0.9},
            "tube_ends": [-0.4, 50.0],
        },
    ],
    ids=["bare-tube", "secondary-and-tube-end"],
)
def test_the_sun_alone_attitudes_image_from_the_sun_grid_is_the_rows_own_within_its_curvature(monkeypatch, optics):
    """The ideal and shared attitudes' image (intercept, misses) is computed at the sun grid's points
    and interpolated onto the rows (issue #26: two of four attitudes' 64 normal-CDF evaluations per row
    saved). Linear interpolation over dt = SUN_GRID_S errs by at most dt^2/8 |f''| for each interpolated
    f (the intercept, the misses) against the truth, the image of the exact attitude at every row; f'' is
    estimated from the truth's second differences at the grid's spacing. The end fraction, the rows' own
    function of the interpolated miss, errs by at most the miss's error over the mirror's length (the
    share of the length past the end). Across sunrise the rows between a grid point below the horizon
    and one above take their own image, bit for bit."""
    from heliostep.results.light import on_tube as light
    from heliostep.results.light.mirror_power import receiver_image
    from heliostep.solar import optics as optics_module

    scenario = validate_scenario(
        {
            "name": "light-grid",
            "site": {"latitude": 40.0, "longitude": 14.25, "altitude": 0.0, "timezone": "Europe/Rome"},
            "window": {"date": "2025-01-21", "start": "07:15", "duration": 3600},  # sunrise at 07:21 CET
            "plant": {"orientation": "NS", "tube_height": 3.0},
            "mirror": {"distance": 2.4, "axis": "secondary"},
            "optics": optics,
        }
    )
    start = pd.Timestamp("2025-01-21 07:15", tz="Europe/Rome")
    seconds = np.arange(0.0, 3601.0, 1.0)
    site, plant = scenario.site.to_site(), scenario.plant.to_plant()
    times = start + pd.to_timedelta(seconds, unit="s")
    ref = panel_angle_reference(times, site, plant, 2.4, axis="secondary").to_numpy()
    trace = pd.DataFrame({"time": seconds, "panel_angle_ref": ref, PANEL_COLUMN: ref + np.radians(0.006)})
    metadata = {"window_start": start.isoformat(), "timezone": "Europe/Rome", "roles": {"panel_angle": PANEL_COLUMN}}

    gridded = light_timeseries(trace, metadata, scenario)
    figures = light_figures(trace, metadata, scenario)
    own = lambda points, grid_attitude, rows, d, h, conf: receiver_image(*rows[1:], d, h, conf)  # noqa: E731
    monkeypatch.setattr(light, "interpolated_image", own)
    exact = light_timeseries(trace, metadata, scenario)
    exact_figures = light_figures(trace, metadata, scenario)

    up = exact["power_ideal_W"].to_numpy() > 0
    assert 0.05 < np.mean(~up) < 0.5  # the window opens with the sun below the horizon
    points = np.arange(0.0, 3601.0, light.SUN_GRID_S)  # the grid from the first row, at t = 0
    below = light.sun_grid(points, metadata, scenario, None)["elevation"] <= 0
    beside = seconds < points[np.flatnonzero(below)[-1] + 1]  # rows with a grid point below the horizon
    assert np.any(beside & up)
    inside = ~beside
    # the truth at every row: the sun grid's values (each a function of its time alone) at the rows' own times
    truth = light.sun_grid(seconds, metadata, scenario, None)
    true_attitudes = {
        "ideal": (truth["ideal_primary"], truth["ideal_secondary"]),
        "shared": (truth["ideal_primary"] - truth["sharing"], truth["ideal_secondary"]),
    }
    length, ends = scenario.optics.mirror_length, optics.get("tube_ends")
    for attitude, (primary, secondary) in true_attitudes.items():
        true_image = receiver_image(truth["sun"], primary, secondary, 2.4, 3.0, scenario.optics)
        bounds = {}
        for key, column in (
            ("intercept", f"intercept_{attitude}"),
            ("longitudinal_miss_m", f"longitudinal_miss_{attitude}_m"),
            ("transverse_miss_m", f"transverse_miss_{attitude}_m"),
        ):
            true = true_image[key][inside]
            # |f''| dt^2 / 8 from the truth's second differences at the grid's spacing
            bounds[key] = np.max(np.abs(np.diff(true[:: int(light.SUN_GRID_S)], 2))) / 8
            error = np.max(np.abs(gridded[column].to_numpy()[inside] - true))
            assert error <= 1.5 * bounds[key] + 1e-12, (attitude, key)  # 1e-12: a picometre, rounding
        assert 0 < bounds["intercept"] < 1e-6  # what the bound is worth: far below the stepping's changes
        if ends is not None:  # the share of the mirror's length past the tube's start: d f_end / d miss <= 1 / length
            true_end = optics_module.end_fraction(true_image["longitudinal_miss_m"], length, 0.0, *ends)[inside]
            assert np.min(true_end) < 0.99  # the tube's start cuts some of the light in the window
            end_error = np.abs(gridded[f"end_fraction_{attitude}"].to_numpy()[inside] - true_end)
            assert np.max(end_error) <= 1.5 * bounds["longitudinal_miss_m"] / length + 1e-12
        # against the rows' own image: P is proportional to gamma f_end, so it moves by P / gamma times
        # gamma's change plus P / f_end times f_end's
        own_gamma, own_end = (exact[f"{key}_{attitude}"].to_numpy() for key in ("intercept", "end_fraction"))
        power = exact[f"power_{attitude}_W"].to_numpy()
        d_gamma = np.max(np.abs(gridded[f"intercept_{attitude}"].to_numpy() - own_gamma))
        d_end = np.max(np.abs(gridded[f"end_fraction_{attitude}"].to_numpy() - own_end))
        per_gamma = np.max(np.divide(power, own_gamma, out=np.zeros_like(power), where=own_gamma > 0))
        per_end = np.max(np.divide(power, own_end, out=np.zeros_like(power), where=own_end > 0))
        power_change = np.max(np.abs(gridded[f"power_{attitude}_W"].to_numpy() - power))
        assert 0 < power_change <= 1.5 * (d_gamma * per_gamma + d_end * per_end) + 1e-12
    # the rows after sunrise, the grid point before them below the horizon: their own image
    for key in ("intercept_ideal", "transverse_miss_ideal_m", "power_shared_W"):
        assert np.array_equal(gridded[key].to_numpy()[beside], exact[key].to_numpy()[beside]), key
    # the reference and the actual attitudes are the rows' own: the same bit for bit
    for key in ("power_reference_W", "power_actual_W", "intercept_actual"):
        assert np.array_equal(gridded[key].to_numpy(), exact[key].to_numpy()), key
    # the energies within the sun grid's interpolation noise (INTERPOLATION_NOISE of the energy, 1e-6)
    noise = INTERPOLATION_NOISE * exact_figures["light_energy_ideal_J"]
    for key in ("light_energy_ideal_J", "light_lost_J", "light_lost_shared_primary_J", "light_lost_reference_law_J"):
        assert figures[key] == pytest.approx(exact_figures[key], abs=noise), key
    assert figures["light_energy_J"] == exact_figures["light_energy_J"]  # the actual's: the rows' own
