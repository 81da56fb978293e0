"""Issue #24: an FMU that ships only its C sources is compiled on first use into the FMU cache, by
content, and run; a second use compiles nothing; sources that do not compile are exit 2 naming the FMU
and the compiler's first error. The FMU is the tests' mini Gain (``tests/data/mini/gain.c``) packed as
sources only, with a modelDescription.xml listing them (FMI 2.0 ``<SourceFiles>``)."""

from __future__ import annotations

import zipfile

import pytest

from heliostep.errors import InputError
from heliostep.fmu.sources import with_platform_binary
from heliostep.paths import scenarios_dir
from heliostep.run import run_scenario

CENTRAL = scenarios_dir() / "jan21-central.yaml"


def source_only_gain(folder, broken: bool = False):
    """``folder/Gain.fmu`` with ``sources/`` and no binary (a C syntax error in it with ``broken``)."""
    from third_party_fmu import MINI_DIR, _model_description

    description = _model_description("Gain").replace(
        '<ModelExchange modelIdentifier="Gain"/>',
        '<ModelExchange modelIdentifier="Gain"><SourceFiles><File name="gain.c"/></SourceFiles></ModelExchange>',
    )
    assert "<SourceFiles>" in description
    source = (MINI_DIR / "gain.c").read_text()
    if broken:
        source = source.replace("dx[0] = m->v[DER_S];", "dx[0] = m->v[DER_S]")
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / "Gain.fmu"
    with zipfile.ZipFile(path, "w") as fmu:
        fmu.writestr("modelDescription.xml", description)
        fmu.writestr("sources/gain.c", source)
        fmu.writestr("sources/mini_fmu.h", (MINI_DIR / "mini_fmu.h").read_text())
    return path


def test_a_source_only_fmu_is_compiled_on_first_use_and_runs_as_first_principles_say(tmp_path):
    gain = source_only_gain(tmp_path / "vendor")
    # u unconnected (start 0): y = k u + b = b and s = integral of y = b t; b = 2 over a 5 s window
    result = run_scenario(CENTRAL, overrides=("window.duration=5", f"fmus.gain={gain}", "parameters.gain.b=2.0"))
    assert result.trace["gain.y"].to_numpy() == pytest.approx(2.0)
    assert result.trace["gain.s"].iloc[-1] == pytest.approx(2.0 * 5.0, rel=1e-6)
    used = result.metadata["fmus"]["gain"]["path"]
    assert "/sources/" in used and used.endswith("Gain.fmu")  # the compiled copy in the cache, not the file given
    with zipfile.ZipFile(used) as copy:
        assert "binaries/linux64/Gain.so" in copy.namelist()
    with zipfile.ZipFile(gain) as original:
        assert not any(name.startswith("binaries/") for name in original.namelist())  # the user's file untouched


def test_the_second_use_finds_the_compiled_copy_in_the_cache(tmp_path):
    gain = source_only_gain(tmp_path / "vendor")
    first = with_platform_binary(gain, tmp_path / "cache")
    stat = first.stat()
    second = with_platform_binary(gain, tmp_path / "cache")
    assert second == first and second.stat().st_mtime_ns == stat.st_mtime_ns and second.stat().st_ino == stat.st_ino
    other = source_only_gain(tmp_path / "other")  # other bytes (the zip's time stamps): a copy of its own
    assert other.read_bytes() != gain.read_bytes() or with_platform_binary(other, tmp_path / "cache") == first
    assert with_platform_binary(other, tmp_path / "cache").parent.parent == first.parent.parent  # CACHE/sources/


def test_sources_that_do_not_compile_are_an_input_error_naming_the_fmu_and_the_first_error(tmp_path):
    gain = source_only_gain(tmp_path / "vendor", broken=True)
    with pytest.raises(InputError) as error:
        run_scenario(CENTRAL, overrides=("window.duration=5", f"fmus.gain={gain}"))
    message = str(error.value)
    assert "fmus.gain" in message and str(gain) in message and "does not compile" in message
    assert "gain.c" in message and "error: expected ';'" in message and "\n" not in message


def test_an_empty_binary_folder_beside_sources_is_compiled_not_taken_for_a_binary(tmp_path):
    gain = source_only_gain(tmp_path / "vendor")
    with zipfile.ZipFile(gain, "a") as fmu:
        fmu.writestr(zipfile.ZipInfo("binaries/linux64/"), b"")  # the folder, no library in it
    compiled = with_platform_binary(gain, tmp_path / "cache")
    assert compiled != gain and compiled.is_relative_to(tmp_path / "cache")
    with zipfile.ZipFile(compiled) as copy:
        assert "binaries/linux64/Gain.so" in copy.namelist()
