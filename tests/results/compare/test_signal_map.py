"""heliostep.results.compare.signal_map: which actual signal each reference signal is compared with, and how."""

from __future__ import annotations

import pytest

from heliostep.errors import InputError
from heliostep.results.compare.signal_map import (
    SignalMatch,
    load_signal_map,
    match_signals,
    parse_map_options,
    roles_of,
    signal_units,
)

REFERENCE = ["time", "motor.tau", "mechanics.theta", "panel_angle_error", "motor.i_a"]
REFERENCE_META = {"role.torque": "motor.tau", "role.rotor_angle": "mechanics.theta", "role.current_a": "motor.i_a"}


def test_roles_of_reads_the_role_keys_only():
    assert roles_of({"role.torque": "m.tau", "unit.m.tau": "N.m", "role.": "x", "scenario": "s"}) == {"torque": "m.tau"}


def test_explicit_then_role_then_name_each_actual_signal_used_once():
    actual = ["time", "V.tau", "V.phi", "panel_angle_error", "motor.i_a", "motor.tau"]
    # the vendor's trace also has a column named motor.tau, but its torque role is V.tau
    actual_meta = {"role.torque": "V.tau", "role.rotor_angle": "V.phi", "role.current_a": "motor.i_a"}
    matches = match_signals(actual, REFERENCE, actual_meta, REFERENCE_META, {"motor.tau": "mechanics.theta"})
    assert matches == {
        "motor.tau": SignalMatch("motor.tau", "V.tau", "role", "torque"),
        "mechanics.theta": SignalMatch("mechanics.theta", "motor.tau", "explicit"),
        "panel_angle_error": SignalMatch("panel_angle_error", "panel_angle_error", "name"),
        "motor.i_a": SignalMatch("motor.i_a", "motor.i_a", "name"),  # a role on the same name: by name
    }
    assert list(matches) == [c for c in REFERENCE if c != "time"]  # the reference's order
    # without roles in the actual: by name only; the renamed signals stay unmatched
    assert set(match_signals(actual, REFERENCE, {}, REFERENCE_META)) == {"motor.tau", "panel_angle_error", "motor.i_a"}
    assert match_signals(actual, REFERENCE)["motor.tau"].actual == "motor.tau"


def test_an_explicit_entry_naming_a_missing_column_is_bad_input():
    with pytest.raises(InputError, match="act.csv has no column 'nope'"):
        match_signals(["time", "a"], REFERENCE, explicit={"nope": "motor.tau"}, actual_name="act.csv")
    with pytest.raises(InputError, match="ref.parquet has no column 'nope'"):
        match_signals(["time", "a"], REFERENCE, explicit={"a": "nope"}, reference_name="ref.parquet")


def test_map_options():
    assert parse_map_options(["V.tau=motor.tau", " V.phi = mechanics.theta "]) == {
        "V.tau": "motor.tau",
        "V.phi": "mechanics.theta",
    }
    for bad, message in (
        (["V.tau"], "expected ACTUAL=REFERENCE"),
        (["=motor.tau"], "expected ACTUAL=REFERENCE"),
        (["V.tau=a", "V.tau=b"], "mapped twice"),
        (["V.a=motor.tau", "V.b=motor.tau"], "target of two actual signals"),
    ):
        with pytest.raises(InputError, match=message):
            parse_map_options(bad)


def test_map_files_yaml_and_csv(tmp_path):
    (tmp_path / "map.yml").write_text("V.tau: motor.tau\nV.phi: mechanics.theta\n")
    (tmp_path / "map.csv").write_text("\ufeffactual,reference\nV.tau,motor.tau\n\nV.phi,mechanics.theta\n")
    expected = {"V.tau": "motor.tau", "V.phi": "mechanics.theta"}
    assert load_signal_map(tmp_path / "map.yml") == expected == load_signal_map(tmp_path / "map.csv")
    (tmp_path / "bad.csv").write_text("from,to\nV.tau,motor.tau\n")
    with pytest.raises(InputError, match="bad.csv: line 1: expected the header 'actual,reference'"):
        load_signal_map(tmp_path / "bad.csv")
    (tmp_path / "short.csv").write_text("actual,reference\nV.tau\n")
    with pytest.raises(InputError, match="short.csv: line 2: expected two signal names"):
        load_signal_map(tmp_path / "short.csv")
    (tmp_path / "bad.yaml").write_text("- V.tau\n")
    with pytest.raises(InputError, match="bad.yaml: expected a mapping"):
        load_signal_map(tmp_path / "bad.yaml")
    with pytest.raises(InputError, match="no such file"):
        load_signal_map(tmp_path / "missing.yaml")


def test_units_from_the_reference_else_the_actual_matched_column():
    matches = {"motor.tau": SignalMatch("motor.tau", "V.tau", "role", "torque"), "x": SignalMatch("x", "V.x", "name")}
    units = signal_units(matches, {"unit.V.tau": "kN.m", "unit.V.x": "m", "unit.time": "s"}, {"unit.motor.tau": "N.m"})
    assert units == {"time": "s", "motor.tau": "N.m", "x": "m"}
