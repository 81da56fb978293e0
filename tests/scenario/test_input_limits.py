"""Input that used to end in a traceback is a clear exit 2 naming the file, key and allowed range
(issue 22, item 11): the YAML reader's limits, dates pandas cannot take, absurd altitudes, windows
ending past pandas' timestamps."""

from __future__ import annotations

import datetime as dt
import time
import zoneinfo

import pytest

from heliostep.errors import InputError
from heliostep.paths import scenarios_dir
from heliostep.scenario import load_scenario
from heliostep.scenario.yaml_io import MAX_DEPTH, MAX_EXPANDED_NODES, read_yaml_file

CENTRAL = scenarios_dir() / "jan21-central.yaml"


def _scenario_with(tmp_path, old: str, new: str):
    text = CENTRAL.read_text()
    assert old in text
    path = tmp_path / "s.yaml"
    path.write_text(text.replace(old, new))
    return path


def test_an_unquoted_date_that_does_not_exist_names_the_key(tmp_path):
    path = _scenario_with(tmp_path, "date: 2025-01-21", "date: 2025-02-29")  # unquoted: a YAML timestamp
    with pytest.raises(InputError, match=r"window\.date: .*day") as unquoted:
        load_scenario(path)
    quoted = _scenario_with(tmp_path, "date: 2025-01-21", 'date: "2025-02-29"')
    with pytest.raises(InputError) as as_text:
        load_scenario(quoted)
    assert str(unquoted.value).split(": ", 1)[1] == str(as_text.value).split(": ", 1)[1]  # the same message


def test_yaml_nested_too_deep_is_bad_yaml_naming_the_line(tmp_path):
    path = tmp_path / "deep.yaml"
    path.write_text("name: x\nsite: " + "[" * 800 + "]" * 800 + "\n")  # before: RecursionError
    with pytest.raises(InputError, match=rf"deep.yaml: not valid YAML: line 2, .*nested deeper than {MAX_DEPTH}"):
        read_yaml_file(path, "scenario")
    fine = tmp_path / "fine.yaml"
    fine.write_text("a: " + "[" * (MAX_DEPTH - 2) + "1" + "]" * (MAX_DEPTH - 2) + "\n")
    value = read_yaml_file(fine, "scenario")["a"]
    for _ in range(MAX_DEPTH - 3):
        (value,) = value
    assert value == [1]


def test_an_alias_bomb_is_refused_at_once(tmp_path):
    """Nine levels of nine aliases each: 9**9 (387 million) leaves if expanded."""
    lines = ['a: &a ["lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol"]']
    for level in range(1, 10):
        name, previous = chr(ord("a") + level), chr(ord("a") + level - 1)
        lines.append(f"{name}: &{name} [" + ", ".join([f"*{previous}"] * 9) + "]")
    path = tmp_path / "bomb.yaml"
    path.write_text("\n".join(lines) + "\n")
    started = time.perf_counter()
    with pytest.raises(
        InputError,
        match=rf"bomb.yaml: not valid YAML: .*more than {MAX_EXPANDED_NODES} values with its aliases expanded",
    ):
        read_yaml_file(path, "scenario")
    assert time.perf_counter() - started < 30  # before: over 60 s and counting
    shared = tmp_path / "shared.yaml"  # aliases within the limit are fine
    shared.write_text("a: &a [1, 2]\nb: *a\nc: *a\n")
    assert read_yaml_file(shared, "scenario") == {"a": [1, 2], "b": [1, 2], "c": [1, 2]}


@pytest.mark.parametrize("date", ["1600-01-21", "1677-12-31", "2262-01-21", "9999-01-21"])
def test_years_outside_pandas_timestamps_are_refused_with_the_range(date):
    with pytest.raises(InputError, match=rf"window\.date: {date}: expected a date in the years 1678 to 2261"):
        load_scenario(CENTRAL, [f"window.date={date}"])


def test_dates_of_local_mean_time_are_refused_naming_the_first_allowed_day():
    """Europe/Rome kept Rome's local mean time, UTC+0:49:56, until 1 November 1893 (the tz database)."""
    rome = zoneinfo.ZoneInfo("Europe/Rome")
    assert rome.utcoffset(dt.datetime(1893, 10, 31, 12)) == dt.timedelta(minutes=49, seconds=56)
    assert rome.utcoffset(dt.datetime(1893, 11, 1, 12)) == dt.timedelta(hours=1)
    with pytest.raises(InputError, match=r"window\.date: 1890-01-21: Europe/Rome .* expected a date from 1893-11-01"):
        load_scenario(CENTRAL, ["window.date=1890-01-21"])
    assert load_scenario(CENTRAL, ["window.date=1893-11-01"]).window.date == dt.date(1893, 11, 1)
    assert load_scenario(CENTRAL, ["window.date=1700-01-21", "site.timezone=UTC"]).window.date.year == 1700


@pytest.mark.parametrize("altitude", [44331, 50000, 1e6, -1e6, -501])
def test_absurd_altitudes_are_refused_with_the_allowed_range(altitude):
    with pytest.raises(InputError, match=r"site\.altitude: .*(less|greater) than or equal to (9000|-500)"):
        load_scenario(CENTRAL, [f"site.altitude={altitude}"])
    for fine in (-430, 8849):  # the Dead Sea's shore, Everest
        assert load_scenario(CENTRAL, [f"site.altitude={fine}"]).site.altitude == fine


@pytest.mark.parametrize("duration", ["1e12", "1e300"])
def test_a_window_ending_past_pandas_timestamps_names_the_duration(duration):
    with pytest.raises(InputError, match=r"window\.duration: .* ends after 2261-12-31"):
        load_scenario(CENTRAL, [f"window.duration={duration}"])


@pytest.mark.parametrize("current", ["1e308", "101", "1e30"])
def test_a_phase_current_beyond_any_stepper_drive_is_refused_with_the_range(current):
    from heliostep.scenario.sections import MAX_PHASE_CURRENT

    with pytest.raises(InputError, match=rf"sequencer\.current: .*less than or equal to {MAX_PHASE_CURRENT:g}"):
        load_scenario(CENTRAL, [f"sequencer.current={current}"])
    assert load_scenario(CENTRAL, ["sequencer.current=100"]).sequencer.current == 100


def test_a_catalogue_current_beyond_any_stepper_drive_is_refused_naming_the_entry(tmp_path):
    from heliostep.scenario.catalogue import load_catalogue, shipped_catalogue_path

    text = shipped_catalogue_path().read_text()
    assert "currents: [3.0, 4.5, 5.9]" in text
    catalogue = tmp_path / "motors.yaml"
    catalogue.write_text(text.replace("currents: [3.0, 4.5, 5.9]", "currents: [3.0, 4.5, 1e30]"))
    with pytest.raises(
        InputError, match=r"motors.yaml: motors\.[\w-]+\.currents: expected phase currents up to 100 A, got 1e\+30"
    ):
        load_catalogue(catalogue)


@pytest.mark.parametrize("name", ["jan21\\ncentral", "jan21\\tcentral", "jan21\\rcentral"])
def test_a_name_with_a_line_break_is_refused_naming_the_file_and_key(name):
    with pytest.raises(InputError, match=r"jan21-central.yaml: name: .*a name is one line of printable text"):
        load_scenario(CENTRAL, [f'name="{name}"'])
