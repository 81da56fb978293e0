"""Issue #24: an FMI 3.0 FMU that ships only its C sources (``sources/`` and FMI 3.0's
``sources/buildDescription.xml``, no binary) is compiled on first use into the FMU cache, by content,
and run; the second use compiles nothing; one byte changed is another FMU, compiled anew. The FMU is
the tests' Lag3 (``tests/data/mini3cs/``: FMI 3.0 Model Exchange and Co-Simulation) packed as sources
only, run here as a Co-Simulation FMU (a sampled component) beside the paper's drive."""

from __future__ import annotations

import zipfile

import numpy as np
import pytest

from heliostep.errors import InputError
from heliostep.fmu.sources import with_platform_binary
from heliostep.paths import scenarios_dir
from heliostep.run import run_scenario
from third_party_fmu import build_mini_fmu
from third_party_fmu3cs import build_lag3_fmu

CENTRAL = scenarios_dir() / "jan21-central.yaml"
T_LAG, H = 0.5, 0.05


def test_a_source_only_fmi3_fmu_is_compiled_on_first_use_and_runs_as_first_principles_say(tmp_path):
    lag = build_lag3_fmu(tmp_path / "vendor", sources_only=True)
    with zipfile.ZipFile(lag) as original:
        assert "sources/buildDescription.xml" in original.namelist()
        assert not any(name.startswith("binaries/") for name in original.namelist())
    # the lag as Co-Simulation at 50 ms, its input u a unit step from a Model Exchange gain (y = b = 1)
    gain = build_mini_fmu("Gain", tmp_path / "vendor")
    overrides = (
        "window.duration=2",
        f"fmus.lag={lag}",
        f"fmus.one={gain}",
        "parameters.one={k: 0.0, b: 1.0}",
        "communication_interval.lag=0.05",
        "connections=[[motor.tau, mechanics.tau], [mechanics.theta, motor.theta], [mechanics.omega, motor.omega],"
        " [one.y, lag.u]]",
    )
    result = run_scenario(CENTRAL, overrides=overrides)
    assert result.complete
    used = result.metadata["fmus"]["lag"]["path"]
    assert "/sources/" in used and used.endswith("Lag3.fmu")  # the compiled copy in the cache, not the file given
    with zipfile.ZipFile(used) as copy:
        assert "binaries/x86_64-linux/Lag3.so" in copy.namelist()  # FMI 3.0's platform tuple folder
    with zipfile.ZipFile(lag) as original:
        assert not any(name.startswith("binaries/") for name in original.namelist())  # the user's file untouched
    # a unit step held at the points: y_k = 1 - exp(-k h / T) exactly at every communication point
    trace = result.trace
    at = trace[np.isclose(trace["time"] / H, np.round(trace["time"] / H), rtol=0, atol=1e-6)]
    after = at.drop_duplicates("time", keep="last")
    k = np.round(after["time"].to_numpy() / H)
    assert len(after) == 41
    np.testing.assert_allclose(after["lag.y"], 1.0 - np.exp(-k * H / T_LAG), rtol=0, atol=1e-12)


def test_the_second_use_finds_the_copy_and_one_byte_changed_is_compiled_anew(tmp_path):
    lag = build_lag3_fmu(tmp_path / "vendor", sources_only=True)
    first = with_platform_binary(lag, tmp_path / "cache")
    assert first != lag and first.is_file()
    stat = first.stat()
    same = build_lag3_fmu(tmp_path / "again", sources_only=True)  # the same bytes elsewhere: the same copy
    assert same.read_bytes() == lag.read_bytes()
    second = with_platform_binary(same, tmp_path / "cache")
    assert second == first and second.stat().st_mtime_ns == stat.st_mtime_ns and second.stat().st_ino == stat.st_ino
    # one byte of a comment in lag3.c changed: another FMU by content, compiled into a folder of its own
    edited = build_lag3_fmu(tmp_path / "edited", sources_only=True, source_edit=("Lag3 --", "Lag3 -="))
    third = with_platform_binary(edited, tmp_path / "cache")
    assert third.parent != first.parent and third.parent.parent == first.parent.parent  # CACHE/sources/KEY16/
    assert first.stat().st_ino == stat.st_ino  # the first copy left as it was
    with zipfile.ZipFile(third) as copy:
        assert b"Lag3 -=" in copy.read("sources/lag3.c") and "binaries/x86_64-linux/Lag3.so" in copy.namelist()


def test_fmi3_sources_that_do_not_compile_are_an_input_error_naming_the_fmu_and_the_first_error(tmp_path):
    broken = build_lag3_fmu(tmp_path, sources_only=True, source_edit=("M->state = TERMINATED;", "M->state = ;"))
    with pytest.raises(InputError) as error:
        with_platform_binary(broken, tmp_path / "cache")
    message = str(error.value)
    assert str(broken) in message and "does not compile" in message and "sources/lag3.c:" in message
    assert "error: expected expression" in message and "\n" not in message
