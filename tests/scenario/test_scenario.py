"""Tests of heliostep.scenario: schema, defaults, error messages, overrides, window bounds."""

from __future__ import annotations

import json
import math
import textwrap

import pandas as pd
import pytest
import yaml

from heliostep.errors import InputError
from heliostep.scenario import (
    DEFAULT_CONNECTIONS,
    Scenario,
    load_scenario,
    validate_scenario,
)

MINIMAL = """\
name: jan21-central
site: {latitude: 40.0, longitude: 14.25, timezone: Europe/Rome}
window: {date: 2025-01-21, start: "10:00", duration: 300}
plant: {tube_height: 3.0}
mirror: {distance: 0.0}
"""

FULL = """\
name: jan21-edge
description: "edge mirror, half stepping"
site: {latitude: 40.0, longitude: 14.25, altitude: 120.0, timezone: Europe/Rome}
window: {date: 2025-01-21, start: "10:00:30", end: "10:30"}
plant: {orientation: EW, azimuth_offset: 5.0, tube_height: 5.0}
mirror: {index: 0, spacing: 0.5, axis: primary, stow: stow, stow_angle: -10.0}
transmission: {pinion_radius: 0.003, lever_arm: 0.25}
fmus: {motor: StepperMotorIdealCurrent, mechanics: ../fmus/Custom.fmu}
parameters: {motor: {K_current: 100.0, R: 1}, mechanics: {}}
connections:
  - [motor.tau, mechanics.tau]
  - [mechanics.theta, motor.theta]
sequencer: {mode: half-step, current: 3.5, step_angle: 0.9}
wind: {moment: -2.5}
solver: {rtol: 1.0e-5, atol: 1.0e-8, max_step: 0.01, max_num_steps: 5000}
output: {interval: 0.02, step_detail: 0.1, step_interval: 0.001}
"""


def write(folder, text, name="scenario.yaml"):
    path = folder / name
    path.write_text(textwrap.dedent(text), encoding="utf-8")
    return path


def load_text(tmp_path, text, overrides=()):
    return load_scenario(write(tmp_path, text), overrides)


def error_of(tmp_path, text, overrides=()):
    path = write(tmp_path, text)
    with pytest.raises(InputError) as info:
        load_scenario(path, overrides)
    return str(info.value), str(path)


# --------------------------------------------------------------------------- valid files
def test_full_scenario_round_trip(tmp_path):
    scenario = load_text(tmp_path, FULL)
    assert scenario.name == "jan21-edge"
    assert scenario.site.altitude == 120.0
    assert scenario.plant.orientation == "EW"
    assert scenario.mirror.axis == "primary" and scenario.mirror.stow == "stow"
    assert scenario.mirror.mirror_distance == pytest.approx(-6 * 0.5)  # index 0 of 13, central is 6
    assert scenario.transmission.pinion_radius == 0.003
    assert scenario.parameters == {"motor": {"K_current": 100.0, "R": 1.0}, "mechanics": {}}
    assert type(scenario.parameters["motor"]["R"]) is int  # kept as written; the master converts it to the FMU's Real
    assert scenario.connection_pairs() == [("motor.tau", "mechanics.tau"), ("mechanics.theta", "motor.theta")]
    assert scenario.sequencer.mode == "half-step" and scenario.sequencer.current == 3.5
    assert scenario.wind.moment == -2.5
    assert scenario.solver.atol == 1e-8 and scenario.solver.max_num_steps == 5000
    assert scenario.output.step_detail == 0.1

    resolved = scenario.resolved_dict()
    assert json.loads(json.dumps(resolved)) == resolved  # plain JSON-able
    assert resolved["window"]["start"] == "10:00:30" and resolved["window"]["end"] == "10:30:00"
    folder = tmp_path / "again"
    folder.mkdir()
    again = load_scenario(write(folder, yaml.safe_dump(resolved)))
    assert again.resolved_dict() == resolved
    assert again.window_bounds() == scenario.window_bounds()


def test_defaults_of_optional_sections(tmp_path):
    scenario = load_text(tmp_path, MINIMAL)
    assert scenario.description is None
    assert scenario.site.altitude == 0.0
    assert scenario.plant.orientation == "NS" and scenario.plant.azimuth_offset == 0.0
    assert (scenario.mirror.axis, scenario.mirror.stow, scenario.mirror.stow_angle) == ("secondary", "hold", 0.0)
    assert (scenario.transmission.pinion_radius, scenario.transmission.lever_arm) == (2.5e-3, 0.3)  # paper Table 2
    assert scenario.fmus == {"motor": "StepperMotor", "mechanics": "PanelMechanics"}
    assert scenario.parameters == {}
    assert scenario.connections is None
    assert scenario.connection_pairs() == [
        ("motor.tau", "mechanics.tau"),
        ("mechanics.theta", "motor.theta"),
        ("mechanics.omega", "motor.omega"),
    ]
    assert DEFAULT_CONNECTIONS == scenario.connection_pairs()
    assert (
        scenario.sequencer.mode,
        scenario.sequencer.current,
        scenario.sequencer.step_angle,
        scenario.sequencer.trigger,
    ) == ("one-phase-on", 5.5, 1.8, "midpoint")
    assert scenario.wind.moment == 0.0
    assert (scenario.solver.rtol, scenario.solver.atol, scenario.solver.max_step, scenario.solver.max_num_steps) == (
        1e-6,
        None,
        None,
        100_000,
    )
    assert (scenario.output.interval, scenario.output.step_detail, scenario.output.step_interval) == (
        0.01,
        0.05,
        0.0005,
    )


def test_null_section_takes_its_defaults(tmp_path):
    scenario = load_text(tmp_path, MINIMAL + "wind:\nparameters: {motor: }\n")
    assert scenario.wind.moment == 0.0
    assert scenario.parameters == {"motor": {}}


def test_yaml_numbers_and_unquoted_clock_times(tmp_path):
    # YAML 1.1 reads 10:00 as the base-60 integer 600 and 1e-7 as a string
    text = MINIMAL.replace('start: "10:00"', "start: 10:30") + "solver: {rtol: 1e-7}\n"
    scenario = load_text(tmp_path, text)
    assert scenario.window_bounds()[0] == pd.Timestamp("2025-01-21 10:30", tz="Europe/Rome")
    assert scenario.solver.rtol == 1e-7


def test_mirror_index_places_the_mirror_in_the_field(tmp_path):
    scenario = load_text(tmp_path, MINIMAL.replace("mirror: {distance: 0.0}", "mirror: {index: 9}"))
    assert scenario.mirror.mirror_distance == pytest.approx(3 * 0.6)  # 3 places from the central, 0.6 m apart


# --------------------------------------------------------------------------- error messages
def test_unknown_key_at_top_level_names_file_and_key(tmp_path):
    message, path = error_of(tmp_path, MINIMAL + "sequencr: {mode: half-step}\n")
    assert path in message
    assert "sequencr: unknown key" in message
    assert "sequencer" in message.split("allowed keys:")[1]


def test_unknown_nested_key_names_the_dotted_path(tmp_path):
    message, path = error_of(tmp_path, MINIMAL.replace("{distance: 0.0}", "{distance: 0.0, colour: red}"))
    assert path in message
    assert "mirror.colour: unknown key" in message
    assert "stow_angle" in message  # lists the allowed keys


def test_bad_literal_lists_the_allowed_values(tmp_path):
    message, path = error_of(tmp_path, MINIMAL + "sequencer: {mode: full-step}\n")
    assert path in message and "sequencer.mode" in message
    for allowed in ("one-phase-on", "two-phase-on", "half-step"):
        assert allowed in message
    assert "full-step" in message


def test_range_errors_name_key_and_bound(tmp_path):
    message, _ = error_of(tmp_path, MINIMAL + "solver: {rtol: 0.5}\n")
    assert "solver.rtol" in message and "0.1" in message
    message, _ = error_of(tmp_path, MINIMAL.replace("latitude: 40.0", "latitude: 95.0"))
    assert "site.latitude" in message and "90" in message and "95" in message


def test_every_error_on_its_own_line(tmp_path):
    text = MINIMAL.replace("tube_height: 3.0", "tube_height: -1") + "sequencer: {current: 0, mode: x}\n"
    message, path = error_of(tmp_path, text)
    lines = message.splitlines()
    assert len(lines) == 3
    assert all(line.startswith(f"{path}: ") for line in lines)
    assert {line.split(": ")[1] for line in lines} == {"plant.tube_height", "sequencer.current", "sequencer.mode"}


def test_a_bool_or_a_string_is_not_a_number(tmp_path):
    message, _ = error_of(tmp_path, MINIMAL + 'sequencer: {current: true, step_angle: "1.8"}\n')
    assert "sequencer.current" in message and "sequencer.step_angle" in message


def test_unknown_timezone_reuses_the_geometry_message(tmp_path):
    message, _ = error_of(tmp_path, MINIMAL.replace("Europe/Rome", "Europe/Roma"))
    assert "site.timezone" in message and "IANA" in message


@pytest.mark.parametrize(
    ("replace", "by", "expected"),
    [
        ("{distance: 0.0}", "{distance: 0.0, index: 6}", "mirror: give exactly one of 'distance' or 'index'"),
        ("{distance: 0.0}", "{}", "mirror: give exactly one of 'distance' or 'index'"),
        ("{distance: 0.0}", "{index: 13}", "mirror.index"),
        ("{distance: 0.0}", "{distance: 1.0, spacing: 0.5}", "mirror.spacing"),
        ("duration: 300", "duration: 300, end: '11:00'", "window: give exactly one of 'end' or 'duration'"),
        ("duration: 300", "end: '09:00'", "window.end: must be after start"),
        ("duration: 300", "duration: 0", "window.duration"),
        ('start: "10:00"', 'start: "10h"', "window.start"),
        ('start: "10:00"', 'start: "24:00"', "window.start"),
        ('start: "10:00", duration: 300', 'start: "18:00", end: sunset', "window.end: must be after the start"),
    ],
)
def test_section_consistency(tmp_path, replace, by, expected):
    assert replace in MINIMAL
    message, path = error_of(tmp_path, MINIMAL.replace(replace, by))
    assert path in message
    assert expected in message


def test_parameters_and_connections_must_name_fmu_instances(tmp_path):
    message, _ = error_of(tmp_path, MINIMAL + "parameters: {motr: {R: 1.0}}\n")
    assert "parameters.motr: unknown FMU instance" in message and "motor, mechanics" in message
    message, _ = error_of(tmp_path, MINIMAL + "connections: [[motor.tau, mechanics.tau], [motor.tau, no_dot]]\n")
    assert "connections[1][1]: expected 'instance.variable'" in message
    text = MINIMAL + "connections: [[motor.tau, mechanic.tau], [motor.v, mechanic.tau]]\n"
    message, _ = error_of(tmp_path, text)
    assert "connections[0][1]: 'mechanic.tau': unknown FMU instance 'mechanic'" in message
    text = MINIMAL + "connections: [[motor.tau, mechanics.tau], [motor.v, mechanics.tau]]\n"
    message, _ = error_of(tmp_path, text)
    assert "connections[1]: 'mechanics.tau' is already the target" in message


def test_dropping_an_fmu_needs_explicit_connections(tmp_path):
    message, _ = error_of(tmp_path, MINIMAL + "fmus: {mechanics: null, drive: DriveSystem}\n")
    assert "connections: the default connections use FMU instance(s) mechanics" in message
    scenario = load_text(
        tmp_path,
        MINIMAL + "fmus: {mechanics: null, motor: null, drive: DriveSystem}\n"
        "connections: []\n"
        "roles: {current_a_ref: drive.i_a_ref, current_b_ref: drive.i_b_ref, "
        "rotor_angle: drive.theta}\n",
    )
    assert scenario.fmus == {"drive": "DriveSystem"} and scenario.connection_pairs() == []


# --------------------------------------------------------------------------- files
def test_missing_file(tmp_path):
    path = tmp_path / "nope.yaml"
    with pytest.raises(InputError, match="nope.yaml: scenario file not found"):
        load_scenario(path)


def test_invalid_yaml_names_file_and_line(tmp_path):
    message, path = error_of(tmp_path, MINIMAL + "sequencer: {mode: [half-step}\n")
    assert message.startswith(f"{path}: not valid YAML")
    assert "line 6" in message


def test_repeated_key_is_an_error(tmp_path):
    message, path = error_of(tmp_path, MINIMAL + "name: other\n")
    assert path in message and "'name' twice" in message and "line 6" in message


@pytest.mark.parametrize("text", ["- name: x\n", "", "just text\n"])
def test_top_level_must_be_a_mapping(tmp_path, text):
    message, path = error_of(tmp_path, text)
    assert message.startswith(f"{path}: the top level must be a mapping")


def test_validate_scenario_from_a_mapping_names_its_source():
    with pytest.raises(InputError, match=r"^memory: name: required key is missing"):
        validate_scenario({}, source="memory")


# --------------------------------------------------------------------------- overrides
def test_set_overrides_number_string_and_new_nested_key(tmp_path):
    scenario = load_text(
        tmp_path,
        MINIMAL,
        [
            "sequencer.current=3",
            "fmus.motor=StepperMotorIdealCurrent",
            "parameters.motor.K_current=100",
            "window.start=10:15",
        ],
    )
    assert scenario.sequencer.current == 3.0 and isinstance(scenario.sequencer.current, float)
    assert scenario.fmus == {"motor": "StepperMotorIdealCurrent", "mechanics": "PanelMechanics"}
    assert scenario.parameters == {"motor": {"K_current": 100.0}}
    assert scenario.window_bounds()[0].strftime("%H:%M") == "10:15"


def test_set_overrides_apply_in_order_and_are_validated(tmp_path):
    scenario = load_text(tmp_path, MINIMAL, ["sequencer.current=3", "sequencer.current=4.5"])
    assert scenario.sequencer.current == 4.5
    message, path = error_of(tmp_path, MINIMAL, ["sequencer.mode=fast"])
    assert path in message and "sequencer.mode" in message and "half-step" in message


@pytest.mark.parametrize(
    ("override", "expected"),
    [
        ("sequencer.current", "expected 'dotted.key=value'"),
        ("=3", "expected 'dotted.key=value'"),
        ("sequencer..current=3", "expected 'dotted.key=value'"),
        ("name.first=x", "name is 'jan21-central', not a mapping"),
        ("sequencer.current=[3", "not valid YAML"),
    ],
)
def test_malformed_set_names_itself(tmp_path, override, expected):
    message, path = error_of(tmp_path, MINIMAL, [override])
    assert path in message
    assert f"--set {override!r}" in message
    assert expected in message


# --------------------------------------------------------------------------- FMU references
def test_fmu_paths_resolve_against_the_scenario_folder(tmp_path, monkeypatch):
    folder = tmp_path / "scenarios"
    folder.mkdir()
    absolute = tmp_path / "elsewhere" / "Abs.fmu"
    text = MINIMAL + f"fmus: {{motor: ../fmus/Motor.fmu, mechanics: PanelMechanics, extra: {absolute}}}\n"
    text += "connections: []\n"
    path = write(folder, text)
    other = tmp_path / "cwd"
    other.mkdir()
    monkeypatch.chdir(other)  # the CWD must not matter
    scenario = load_scenario(path)
    assert scenario.fmu_reference("motor") == tmp_path / "fmus" / "Motor.fmu"
    assert scenario.fmu_reference("mechanics") == "PanelMechanics"
    assert scenario.fmu_reference("extra") == absolute
    with pytest.raises(InputError, match="no FMU instance 'drive'"):
        scenario.fmu_reference("drive")


def test_fmu_paths_of_a_relative_scenario_path(tmp_path, monkeypatch):
    (tmp_path / "cases").mkdir()
    write(tmp_path / "cases", MINIMAL + "fmus: {motor: Motor.fmu}\n")
    monkeypatch.chdir(tmp_path)
    scenario = load_scenario("cases/scenario.yaml")
    assert scenario.fmu_reference("motor") == tmp_path / "cases" / "Motor.fmu"


def test_fmu_paths_without_a_file_resolve_against_the_cwd(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    data = yaml.safe_load(MINIMAL)
    data["window"]["date"] = "2025-01-21"
    data["fmus"] = {"motor": "sub/Motor.fmu"}
    scenario = validate_scenario(data)
    assert scenario.fmu_reference("motor") == tmp_path / "sub" / "Motor.fmu"
    assert isinstance(Scenario.model_validate(data).fmu_reference("mechanics"), str)


# --------------------------------------------------------------------------- window bounds
def test_window_bounds_in_local_time(tmp_path):
    start, end = load_text(tmp_path, MINIMAL).window_bounds()
    assert str(start.tz) == "Europe/Rome"
    assert start.tz_convert("UTC") == pd.Timestamp("2025-01-21 09:00", tz="UTC")  # CET = UTC+1 in winter
    assert end - start == pd.Timedelta(seconds=300)
    summer = load_text(
        tmp_path, MINIMAL.replace("2025-01-21", "2025-07-01").replace("duration: 300", "end: '10:30:15'")
    )
    start, end = summer.window_bounds()
    assert start.tz_convert("UTC") == pd.Timestamp("2025-07-01 08:00", tz="UTC")  # CEST = UTC+2
    assert end.tz_convert("UTC") == pd.Timestamp("2025-07-01 08:30:15", tz="UTC")


def test_nonexistent_local_time_is_an_error(tmp_path):
    # clocks jump from 02:00 to 03:00 in Rome on 2025-03-30
    message, _ = error_of(tmp_path, MINIMAL.replace("2025-01-21", "2025-03-30").replace('"10:00"', '"02:30"'))
    assert "window.start" in message and "daylight saving" in message


def first_principles_sun_events(date, latitude, longitude):
    """Sunrise and sunset [min after 00:00 UTC] from NOAA's general solar position formulas.

    Spencer's (1971) series for declination and equation of time, the sunrise hour
    angle for a zenith of 90.833 deg (refraction plus solar radius).
    """
    gamma = 2 * math.pi / 365 * (date.day_of_year - 1)
    eqtime = 229.18 * (
        0.000075
        + 0.001868 * math.cos(gamma)
        - 0.032077 * math.sin(gamma)
        - 0.014615 * math.cos(2 * gamma)
        - 0.040849 * math.sin(2 * gamma)
    )
    decl = (
        0.006918
        - 0.399912 * math.cos(gamma)
        + 0.070257 * math.sin(gamma)
        - 0.006758 * math.cos(2 * gamma)
        + 0.000907 * math.sin(2 * gamma)
        - 0.002697 * math.cos(3 * gamma)
        + 0.00148 * math.sin(3 * gamma)
    )
    lat = math.radians(latitude)
    cos_hour = math.cos(math.radians(90.833)) / (math.cos(lat) * math.cos(decl)) - math.tan(lat) * math.tan(decl)
    hour = math.degrees(math.acos(cos_hour))
    return 720 - 4 * (longitude + hour) - eqtime, 720 - 4 * (longitude - hour) - eqtime


def test_sunrise_and_sunset_window(tmp_path):
    text = MINIMAL.replace('start: "10:00", duration: 300', "start: sunrise, end: sunset")
    start, end = load_text(tmp_path, text).window_bounds()
    assert str(start.tz) == "Europe/Rome"
    day = pd.Timestamp("2025-01-21")
    # plausible range for 40 deg N on 21 January, in CET
    assert day + pd.Timedelta(hours=7) < start.tz_localize(None) < day + pd.Timedelta(hours=8)
    assert day + pd.Timedelta(hours=16, minutes=30) < end.tz_localize(None) < day + pd.Timedelta(hours=17, minutes=45)
    sunrise_utc, sunset_utc = first_principles_sun_events(day, 40.0, 14.25)
    midnight_utc = pd.Timestamp("2025-01-21", tz="UTC")
    assert abs((start - midnight_utc) / pd.Timedelta(minutes=1) - sunrise_utc) < 3.0
    assert abs((end - midnight_utc) / pd.Timedelta(minutes=1) - sunset_utc) < 3.0


def test_sunrise_with_duration(tmp_path):
    text = MINIMAL.replace('start: "10:00"', "start: sunrise")
    start, end = load_text(tmp_path, text).window_bounds()
    assert end - start == pd.Timedelta(seconds=300)
    assert start.hour == 7


def test_polar_night_has_no_sunrise(tmp_path):
    text = MINIMAL.replace("latitude: 40.0", "latitude: 80.0").replace('start: "10:00"', "start: sunrise")
    message, _ = error_of(tmp_path, text)
    assert "window.start: the sun has no sunrise" in message
