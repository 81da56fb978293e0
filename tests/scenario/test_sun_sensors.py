"""The shipped sun sensor presets (heliostep/data/sun_sensors.yaml) and their loader."""

from __future__ import annotations

import math

import pytest
from fmpy import read_model_description

from heliostep.errors import InputError
from heliostep.scenario.sun_sensors import (
    PARAMETER_KEYS,
    load_sun_sensors,
    shipped_sun_sensors_path,
    sun_sensor,
)


def test_the_datasheet_preset_has_the_datasheet_s_values():
    """Solar MEMS SSOC-D60 (Doc. SSOCD60-14-MAN-119 rev. 1.19, page 1): field of view +-60 deg, precision
    0.05 deg; the mounting (k_ray 2), the WMO threshold and the isotropic-sky share as the file says."""
    preset = dict(sun_sensor("ssoc-d60").parameters)
    assert preset == {
        "k_ray": 2.0,
        "fov": pytest.approx(math.radians(60.0), rel=1e-15),
        "offset": 0.0,
        "threshold": 120.0,
        "diffuse_view": pytest.approx(2 / math.pi * math.sin(math.pi / 3) * math.atan(math.sin(math.pi / 3))),
    }
    assert sun_sensor("ssoc-d60").noise_std == pytest.approx(math.radians(0.05), rel=1e-15)
    assert sun_sensor("ssoc-d60").signal_noise_std == pytest.approx(math.radians(0.05) / math.sqrt(3.0))


def test_the_seed_001_cross_faces_the_sun():
    preset = dict(sun_sensor("cross-001").parameters)
    assert preset["k_ray"] == 1.0 and preset["fov"] == pytest.approx(math.pi / 4)
    assert preset["diffuse_view"] == pytest.approx(math.sqrt(2.0) / 4) and preset["threshold"] == 120.0
    assert sun_sensor("cross-001").noise_std == 0.01


def test_every_preset_sets_the_fmu_s_parameters_with_a_source(fmu_paths):
    """Each preset's keys are parameters of the built SunSensor FMU, and each names its maker and document."""
    variables = {v.name: v for v in read_model_description(str(fmu_paths["SunSensor"])).modelVariables}
    presets = load_sun_sensors()
    assert list(presets) == ["ssoc-d60", "cross-001"]
    for preset in presets.values():
        assert set(preset.parameters) == set(PARAMETER_KEYS)
        assert all(variables[name].causality == "parameter" for name in preset.parameters)
        assert {name: variables[name].unit for name in preset.parameters} == PARAMETER_KEYS
        assert preset.maker.strip() and preset.document.strip()
    # the FMU's defaults are the datasheet preset's
    assert {name: float(variables[name].start) for name in PARAMETER_KEYS} == pytest.approx(
        presets["ssoc-d60"].parameters, rel=1e-15
    )


def test_an_unknown_name_names_the_file_and_the_presets():
    with pytest.raises(InputError) as raised:
        dict(sun_sensor("ssoc").parameters)
    message = str(raised.value)
    assert str(shipped_sun_sensors_path()) in message and "'ssoc'" in message
    assert "close: ssoc-d60" in message and "the presets are: ssoc-d60, cross-001" in message
    with pytest.raises(InputError, match="unknown sun sensor 'nope'"):
        sun_sensor("nope")


def test_values_come_from_the_file(tmp_path):
    text = (
        shipped_sun_sensors_path()
        .read_text()
        .replace("    threshold: 120.0  # assumed: the datasheet", "    threshold: 80.0  #", 1)
    )
    path = tmp_path / "sensors.yaml"
    path.write_text(text)
    assert sun_sensor("ssoc-d60", path).parameters["threshold"] == 80.0
    assert sun_sensor("cross-001", path).parameters["threshold"] == 120.0


@pytest.mark.parametrize(
    ("old", "new", "problem"),
    [
        (
            "    fov: 1.0471975511965976",
            "    fov: 1.6",
            r"sun_sensors\.ssoc-d60\.fov: expected between 0 and pi/2 \[rad\]",
        ),
        (
            "    noise_std: 0.01\n",
            "    noise_std: -0.01\n",
            r"sun_sensors\.cross-001\.noise_std: expected >= 0 \[rad\]",
        ),
        ("    k_ray: 1.0", "    k_ray: one", r"sun_sensors\.cross-001\.k_ray: expected a number \[1\]"),
        ("    offset: 0.0  # the", "    offsets: 0.0  # the", r"sun_sensors\.ssoc-d60\.offset: missing"),
        ("    offset: 0.0\n", "    offset: 0.0\n    gain: 2\n", r"sun_sensors\.cross-001\.gain: unknown key"),
    ],
)
def test_a_bad_value_is_refused_naming_the_file_and_the_key(tmp_path, old, new, problem):
    text = shipped_sun_sensors_path().read_text()
    assert old in text
    path = tmp_path / "sensors.yaml"
    path.write_text(text.replace(old, new, 1))
    with pytest.raises(InputError, match=f"{path}: {problem}"):
        load_sun_sensors(path)
