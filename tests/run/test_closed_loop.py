"""Closed-loop and hybrid tracking through the co-simulation (``tracking:``), against figures computed here.

The tracking law is :func:`heliostep.solar.panel_angle_reference` (checked against the paper elsewhere); what
is under test is the loop: the panel angle the FMUs reach with the steps the controller decides from the sun
sensor's FMU, and the bounds first principles put on its error."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from heliostep.errors import InputError
from heliostep.run import RunFailed, RunOptions, run_scenario
from heliostep.scenario import load_scenario
from heliostep.scenario.sun_sensors import sun_sensor
from heliostep.solar import panel_angle_reference

SCENARIO = "jan21-central"
#: The paper's transmission (Table 2) and the sequencer's full step.
PINION, LEVER, STEP = 2.5e-3, 0.3, np.radians(1.8)


def _run(*overrides: str):
    scenario = load_scenario(SCENARIO, ("output.step_detail=0", "output.interval=0.5", *overrides))
    return scenario, run_scenario(scenario, RunOptions(supervise=False))


def _ideal(scenario, times: np.ndarray) -> np.ndarray:
    """The tracking law's panel angle [rad] at run times [s], computed here from the window's start."""
    start, _ = scenario.window_bounds()
    index = start + pd.to_timedelta(times, unit="s")
    site, plant = scenario.site.to_site(), scenario.plant.to_plant()
    return panel_angle_reference(
        index, site, plant, scenario.mirror.mirror_distance, axis=scenario.mirror.axis
    ).to_numpy()


def _panel_step(panel: np.ndarray) -> np.ndarray:
    """One full step of the rotor as panel angle [rad]: d theta_p = (r / s) cos^2(theta_p) d theta ([paper], eq. 14)."""
    return PINION / LEVER * np.cos(panel) ** 2 * STEP


def _errors_at_samples(scenario, result, period: float, after: float = 10.0):
    """Tracking law minus the panel's angle [rad] just before each sample instant after ``after`` [s]
    (the rings of the steps decided at the previous sample decayed), and one panel step there."""
    rows = result.trace.drop_duplicates("time", keep="first").set_index("time")
    times = np.arange(after, scenario.window.duration, period) - 1e-3
    panel = np.interp(times, rows.index.to_numpy(), rows["mechanics.theta_p"].to_numpy())
    return _ideal(scenario, times) - panel, _panel_step(panel)


@pytest.mark.parametrize("dead_band", [0.005, 0.02])
def test_a_perfect_sensor_keeps_the_closed_loop_within_its_dead_band_and_one_panel_step(dead_band, fmu_paths):
    scenario, result = _run(
        "tracking.mode=closed_loop",
        "tracking.noise_std=0",
        f"tracking.dead_band={dead_band}",
        "tracking.sample_period=2",
    )
    error, step = _errors_at_samples(scenario, result, scenario.tracking.sample_period)
    times = np.arange(0.0, scenario.window.duration, 10.0)
    drift = np.abs(_ideal(scenario, times + scenario.tracking.sample_period) - _ideal(scenario, times))
    assert drift.max() < 0.5 * step.min()  # the law moves less than half a step between readings: the bound holds
    assert np.all(np.abs(error) <= np.radians(dead_band) + step), np.degrees(np.abs(error).max())
    assert result.summary["steps_commanded"] > 0 and result.summary["steps_lost"] == 0


def test_a_clock_offset_costs_open_loop_the_rate_times_the_offset_and_the_closed_loops_nothing(fmu_paths):
    offset, dead_band = 120.0, 0.005  # [s], [deg]
    scenario, open_loop = _run(f"faults.clock_offset={offset}")
    # open loop steps to the law's angle offset seconds later: its error is the law's rate times the offset
    times = np.arange(10.0, scenario.window.duration, 5.0)
    rate = (_ideal(scenario, times + 1.0) - _ideal(scenario, times - 1.0)) / 2.0  # [rad/s], differentiated here
    rows = open_loop.trace.drop_duplicates("time", keep="first").set_index("time")
    panel = np.interp(times, rows.index.to_numpy(), rows["mechanics.theta_p"].to_numpy())
    error = _ideal(scenario, times) - panel
    assert np.all(np.abs(error - (-rate * offset)) <= _panel_step(panel)), np.degrees(error + rate * offset)
    assert np.abs(rate * offset).min() > 5 * _panel_step(panel).max()  # a lag the loop must remove
    for mode in ("closed_loop", "hybrid"):
        scenario, closed = _run(
            f"faults.clock_offset={offset}",
            f"tracking.mode={mode}",
            "tracking.noise_std=0",
            f"tracking.dead_band={dead_band}",
        )
        error, step = _errors_at_samples(scenario, closed, scenario.tracking.sample_period, after=30.0)
        assert np.all(np.abs(error) <= np.radians(dead_band) + step), (mode, np.degrees(np.abs(error).max()))


def test_seed_001s_scheme_keeps_the_error_within_half_its_move_once_balanced(fmu_paths):
    move = 10.0  # [deg], seed 001's delta beta; balanced within half of it
    scenario, result = _run(
        "tracking.mode=closed_loop",
        "tracking.sensor=cross-001",
        f"tracking.move={move}",
        f"tracking.dead_band={move / 2}",
        "faults.mounting_offset=12",  # the sensor mounted 12 deg off: the loop moves until it reads balance
        "window.duration=120",
    )
    error, step = _errors_at_samples(scenario, result, scenario.tracking.sample_period, after=60.0)
    # the sensor's zero is 12 deg off the law, so the panel settles within move / 2 of 12 deg / k_ray (1)
    assert np.all(np.abs(np.abs(error) - np.radians(12.0)) <= np.radians(move / 2) + step)
    assert result.summary["steps_commanded"] >= round(np.radians(move) * LEVER / PINION / STEP * 0.9)
    assert result.summary["steps_lost"] == 0  # moves at the default step rate, from rest


def test_a_stuck_driver_costs_open_loop_its_steps_in_whole_periods_and_the_closed_loop_one_sample(fmu_paths):
    span = (60.0, 200.0)  # [s] the driver ignores the steps
    scenario, open_loop = _run(f"faults.stuck=[{span[0]}, {span[1]}]")
    steps = np.asarray(open_loop.metadata["drive"]["step_times"])
    ignored = int(np.sum((steps >= span[0]) & (steps < span[1])))
    # taken up at the span's end, the rotor goes to the nearest detent of the phase commanded then: it
    # moves by the ignored steps less whole electrical periods (4 full steps, one-phase-on)
    moved = (ignored + 2) % 4 - 2
    assert ignored >= 4 and open_loop.summary["steps_lost"] == ignored - moved
    rows = open_loop.trace.drop_duplicates("time", keep="first").set_index("time")
    after = np.arange(span[1] + 5.0, scenario.window.duration, 5.0)
    panel = np.interp(after, rows.index.to_numpy(), rows["mechanics.theta_p"].to_numpy())
    behind = (_ideal(scenario, after) - panel) / _panel_step(panel)  # [panel steps]
    assert np.all(np.abs(behind - (ignored - moved)) <= 1.0), behind
    loop = ("tracking.mode=closed_loop", "tracking.noise_std=0", "tracking.dead_band=0.005", "tracking.sample_period=2")
    scenario, closed = _run(f"faults.stuck=[{span[0]}, {span[1]}]", *loop)
    assert closed.summary["steps_lost"] > 0  # the loop went on stepping while the driver was stuck
    error, step = _errors_at_samples(scenario, closed, 2.0, after=span[1] + 2.0 + 2.0)  # one sample and its move
    assert np.all(np.abs(error) <= np.radians(0.005) + step), np.degrees(np.abs(error).max())


def test_under_a_cloud_the_closed_loop_holds_and_catches_up_and_the_hybrid_follows_the_law(fmu_paths):
    cloud = (60.0, 240.0)  # [s] the direct irradiance cut to 5 %: the sensor is dark (under its threshold)
    loop = ("tracking.noise_std=0", "tracking.dead_band=0.005", "tracking.sample_period=2")
    clouds = f"tracking.clouds=[{{start: {cloud[0]}, end: {cloud[1]}, dni_fraction: 0.05}}]"
    scenario, open_loop = _run()
    law_steps = np.asarray(open_loop.metadata["drive"]["step_times"])
    under = (law_steps >= cloud[0]) & (law_steps < cloud[1])
    assert under.sum() >= 3  # the law moves the panel by steps under the cloud
    lost = {}
    for mode in ("closed_loop", "hybrid"):
        scenario, result = _run(f"tracking.mode={mode}", clouds, *loop)
        steps = np.asarray(result.metadata["drive"]["step_times"])
        during = int(np.sum((steps >= cloud[0] + scenario.tracking.sample_period) & (steps < cloud[1])))
        if mode == "closed_loop":  # dark: it holds its angle, the error grows as the law moves on
            assert during == 0
            error, _ = _errors_at_samples(scenario, result, 2.0, after=cloud[1] - 10.0)
            assert abs(error[0]) > 2 * np.radians(0.005)
        else:  # dark: it follows the law's steps
            assert during == int(np.sum((law_steps >= cloud[0] + 2.0) & (law_steps < cloud[1])))
        # once the sun is back, within a sample and its move, the error is within the dead band and a step
        error, step = _errors_at_samples(scenario, result, 2.0, after=cloud[1] + 4.0)
        assert np.all(np.abs(error) <= np.radians(0.005) + step), (mode, np.degrees(np.abs(error).max()))
        # the light the cloud takes: 95 % of the clear window's over its length (DNI nearly steady over 5 minutes)
        clear = open_loop.summary["light_energy_ideal_J"]
        taken = clear - result.summary["light_energy_ideal_J"]
        assert taken == pytest.approx(0.95 * clear * (cloud[1] - cloud[0]) / scenario.window.duration, rel=0.01)
        lost[mode] = result.summary["light_lost_J"]
    assert lost["closed_loop"] > lost["hybrid"] + 0.1  # [J] the closed loop's catching up costs light; not the hybrid's


def test_the_tracking_loop_figure_draws_the_law_the_panel_the_error_the_signal_and_the_light(fmu_paths):
    from heliostep.plots.run import run_figures

    scenario, result = _run("tracking.mode=closed_loop", "tracking.sample_period=2")
    (name, figure), *_ = run_figures(result.trace, result.metadata, only={"tracking_loop.png"})
    assert name == "tracking_loop.png" and figure is not None
    angles, error, signal, light = figure.axes[:4]
    trace = result.trace
    drawn = {line.get_label(): line.get_ydata() for ax in (angles, error, signal, light) for line in ax.get_lines()}
    for label, column, scale in (
        ("panel - law", "panel_angle_error", np.degrees(1.0)),
        ("(A - B) / (A + B)", "sensor.signal", 1.0),
        ("A + B", "sensor.irradiance", 1.0),
    ):  # every row's extremes drawn (thinned to the pixels, never cut)
        values = trace[column].to_numpy() * scale
        assert np.max(drawn[label]) == pytest.approx(values.max()) and np.min(drawn[label]) == pytest.approx(
            values.min()
        )


def test_a_weather_files_direct_and_diffuse_light_reach_the_sensor(tmp_path, fmu_paths):
    from weather_files import write_tmy3

    def dni(hour):
        return 600.0 + 20.0 * hour  # [W/m2], the mean of the hour ending then

    def dhi(hour):
        return 40.0 + 10.0 * hour

    weather = write_tmy3(tmp_path / "site.csv", longitude=14.25, dni_of_hour=dni, dhi_of_hour=dhi)
    scenario, result = _run("tracking.mode=closed_loop", f"optics.weather_file={weather}", "tracking.sample_period=2")
    rows = result.trace.drop_duplicates("time", keep="last").set_index("time")
    samples = np.arange(2.0, scenario.window.duration - 2.0, 2.0)
    # 10:00 + t local standard time: the means of the hours ending 10:00 and 11:00 placed at 9:30 and 10:30
    share = (1800.0 + samples) / 3600.0
    expected_dni = dni(10) + share * (dni(11) - dni(10))
    expected_dhi = dhi(10) + share * (dhi(11) - dhi(10))
    diffuse_view = sun_sensor("ssoc-d60").parameters["diffuse_view"]
    seen = rows["sensor.irradiance"].reindex(samples + 1.0, method="nearest").to_numpy()  # given at each sample
    np.testing.assert_allclose(seen, expected_dni + 2.0 * diffuse_view * expected_dhi, rtol=1e-9)  # A + B


def test_the_loops_figures_do_not_move_with_the_output_grid_nor_its_steps_with_the_tolerance(fmu_paths):
    """The readings come from the solution at the sample instants, not from the output rows: another grid
    gives the same steps and figures; a tighter tolerance the same steps (the figures within the solver's)."""
    options = RunOptions(supervise=False, keep_trace=False)
    runs = {
        setting: run_scenario("jan21-closed-loop", options, overrides=overrides).summary
        for setting, overrides in (
            ("default", ()),
            ("coarse", ("output.interval=1", "output.step_detail=0")),
            ("tight", ("solver.rtol=1e-8",)),
        )
    }
    for key in ("steps_commanded", "max_tracking_error_deg", "peak_torque_Nm"):
        assert runs["coarse"][key] == runs["default"][key], key
    # an integral over the solution's rows, which take the output rows too: within 1e-6, as open loop's (docs/sweep.md)
    assert runs["coarse"]["electrical_energy_J"] == pytest.approx(runs["default"]["electrical_energy_J"], rel=1e-6)
    assert runs["tight"]["steps_commanded"] == runs["default"]["steps_commanded"] > 0
    assert runs["tight"]["max_tracking_error_deg"] == pytest.approx(runs["default"]["max_tracking_error_deg"], rel=1e-6)


def test_a_closed_loop_run_that_fails_keeps_its_rows_and_the_steps_it_decided_up_to_there(fmu_paths):
    # 2 A against 110 N.m: every step slips a whole electrical period back, the loop steps on, the wind
    # turns the panel out of the transmission's range and the mechanics FMU stops the run
    scenario = load_scenario(
        "jan21-weak-motor",
        ("tracking.mode=closed_loop", "tracking.noise_std=0", "tracking.dead_band=0.005", "tracking.sample_period=2"),
    )
    with pytest.raises(RunFailed) as caught:
        run_scenario(scenario, RunOptions(supervise=False))
    run = caught.value.result
    assert not run.complete and run.reason == "failed" and 0 < run.time_reached < scenario.window.duration
    trace = run.trace
    assert trace["time"].iloc[-1] == pytest.approx(run.time_reached, abs=1e-9)
    steps = np.asarray(run.metadata["drive"]["step_times"])
    assert len(steps) > 0 and steps.max() <= run.time_reached
    indices = run.metadata["drive"]["step_indices"]
    assert trace["step_index"].iloc[-1] == indices[-1]  # the trace ends on the last step decided
    assert run.summary["steps_lost"] >= 4 * (len(steps) // 2)  # most steps slip a whole period (4 full steps)


GUST = (100.0, 130.0)  # [s] the wind at 30 m/s (20 before and after, 2 s ramps)
#: A drive at 0.5 A, stepping against the wind in the afternoon: it holds 20 m/s and slips under 30 m/s (and
#: at 20 m/s too when stepped at the loop's default 50 steps/s: its moves back go at 10).
WINDY = (
    "window.start=15:00",
    "window.duration=400",
    "sequencer.current=0.5",
    "wind.stow_speed=null",
    f"wind.profile=[[0, 20], [{GUST[0]}, 20], [{GUST[0] + 2}, 30], [{GUST[1]}, 30], [{GUST[1] + 2}, 20], [400, 20]]",
)


def test_a_gust_costs_open_loop_its_lost_steps_for_good_and_the_closed_loop_the_move_back(fmu_paths):
    scenario, open_loop = _run(*WINDY)
    lost = open_loop.summary["steps_lost"]  # signed: steps the wind took in its own direction
    assert abs(lost) >= 4
    rows = open_loop.trace.drop_duplicates("time", keep="first").set_index("time")
    after = np.arange(GUST[1] + 10.0, scenario.window.duration, 5.0)
    panel = np.interp(after, rows.index.to_numpy(), rows["mechanics.theta_p"].to_numpy())
    behind = (np.tan(_ideal(scenario, after)) - np.tan(panel)) * LEVER / PINION / STEP  # [full steps], eq. 14
    assert np.all(np.abs(behind - lost) <= 1.0), behind  # the error the lost steps make, for good
    loop = ("tracking.mode=closed_loop", "tracking.noise_std=0", "tracking.dead_band=0.005", "tracking.sample_period=2")
    collimated = "parameters.sensor.diffuse_view=0"  # no diffuse light: a reading's error estimate is exact
    scenario, closed = _run(*WINDY, *loop, "tracking.step_rate=10", collimated)
    # the wind's moment on the panel where the loop keeps it: the open loop's, whose commanded angle is within
    # a step of the law (the closed loop's commanded index took up the steps that slipped)
    later = np.arange(GUST[1] + 70.0, scenario.window.duration, 10.0)
    moments = [np.interp(later, r["time"].to_numpy(), r["m_ext"].to_numpy()) for r in (open_loop.trace, closed.trace)]
    assert np.allclose(moments[1], moments[0], rtol=0.01), moments
    # the gust over, the loop steps the panel back at its step rate without slipping: the steps it needs from
    # the panel's angle then (eq. 14), a reading before and one after; then each reading takes off most of the
    # rest, at least 40 % (its commanded index took up the slipped steps, so it converts the error at another
    # transmission ratio than the panel's) until the error is within the dead band and a step for good
    rows = closed.trace.drop_duplicates("time", keep="first").set_index("time")
    end = GUST[1] + 2.0
    panel = np.interp(end, rows.index.to_numpy(), rows["mechanics.theta_p"].to_numpy())
    needed = abs(np.tan(_ideal(scenario, np.array([end]))[0]) - np.tan(panel)) * LEVER / PINION / STEP
    assert needed > 100  # the loop slipped under the gust too
    back = end + needed / scenario.tracking.step_rate + 2 * scenario.tracking.sample_period
    errors, step = _errors_at_samples(scenario, closed, 2.0, after=np.ceil(back / 2.0) * 2.0)
    within = np.abs(errors) <= np.radians(0.005) + step
    first = int(np.argmax(within))
    assert np.all(within[first:]) and first < len(within) // 2, np.degrees(errors)
    assert np.all(np.abs(errors[1 : first + 1]) < 0.6 * np.abs(errors[:first]))


def test_a_loop_in_a_wind_that_stows_the_panel_is_refused_naming_the_key(fmu_paths):
    with pytest.raises(InputError, match="wind.stow_speed"):
        _run("tracking.mode=closed_loop", "wind.speed=15")  # above the stow speed, 12 m/s


def test_a_loop_with_idle_current_reduction_drops_each_steps_current_after_the_delay_and_tracks_as_before(fmu_paths):
    loop = ("tracking.mode=closed_loop", "tracking.noise_std=0", "tracking.dead_band=0.005", "tracking.sample_period=2")
    scenario, result = _run(*loop, "sequencer.idle_current_fraction=0.5", "sequencer.idle_delay=0.5")
    delay, full = scenario.sequencer.idle_delay, scenario.sequencer.current
    trace = result.trace
    steps = np.asarray(result.metadata["drive"]["step_times"])
    assert len(steps) >= 5 and np.all(np.diff(steps) > delay)  # every step rests longer than the delay
    # the reference currents' magnitude: full from each step (and the start) for the delay, then half
    magnitude = np.hypot(trace["i_a_ref"].to_numpy(), trace["i_b_ref"].to_numpy())
    time = trace["time"].to_numpy()
    since = time - np.concatenate([[0.0], steps])[np.searchsorted(steps, time, side="right")]
    later = (since > delay + 1e-9) & np.r_[True, time[1:] != time[:-1]]  # the first row at a repeated time
    sooner = (since < delay - 1e-9) & np.r_[time[1:] != time[:-1], True]  # the last row at a repeated time
    assert np.allclose(magnitude[later], 0.5 * full) and np.allclose(magnitude[sooner], full)
    error, step = _errors_at_samples(scenario, result, 2.0)
    assert np.all(np.abs(error) <= np.radians(0.005) + step) and result.summary["steps_lost"] == 0


def test_a_loops_currents_under_idle_reduction_and_a_stuck_driver_are_open_loops_on_the_same_steps(fmu_paths):
    """The rules of heliostep.drive.sequencer (idle drops, then the stuck span's changes ignored and the last
    taken up at its end; tested there against their definitions) applied to the steps the hybrid decided."""
    from heliostep.drive.sequencer import idle_currents, stuck_currents

    loop = ("tracking.mode=hybrid", "tracking.sample_period=2", "faults.stuck=[60, 140]")
    scenario, result = _run(*loop, "sequencer.idle_current_fraction=0.5", "sequencer.idle_delay=0.5")
    inputs = result.inputs
    times, i_a, i_b = idle_currents(inputs.schedule, inputs.sequencer, inputs.duration)
    changes, (i_a, i_b) = stuck_currents(np.asarray(times[1:]), [i_a, i_b], scenario.faults.stuck)
    time = result.trace["time"].to_numpy()
    between = ~np.isin(np.round(time, 9), np.round(changes, 9))  # rows not at a change (one side or the other)
    expected = np.searchsorted(changes, time[between], side="right")
    assert result.summary["steps_lost"] > 0 and len(changes) > 2 * len(inputs.schedule) // 3
    assert np.array_equal(result.trace["i_a_ref"].to_numpy()[between], np.asarray(i_a)[expected])
    assert np.array_equal(result.trace["i_b_ref"].to_numpy()[between], np.asarray(i_b)[expected])
