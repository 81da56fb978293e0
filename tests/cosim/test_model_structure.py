"""A modelDescription.xml whose ModelStructure no longer matches its variables (variables inserted
before the others, one declared twice) is an InputError naming the FMU, not an AttributeError."""

from __future__ import annotations

import re
import zipfile

import pytest

from heliostep.cosim import read_fmu
from heliostep.errors import InputError
from third_party_fmu import build_mini_fmu


@pytest.fixture(scope="module")
def lag_fmu(tmp_path_factory):
    return build_mini_fmu("Lag", tmp_path_factory.mktemp("lag"))


def _with_description(fmu, tmp_path, edit):
    """A copy of ``fmu`` whose modelDescription.xml is ``edit(text)``."""
    copy = tmp_path / fmu.name
    with zipfile.ZipFile(fmu) as original, zipfile.ZipFile(copy, "w") as archive:
        for entry in original.infolist():
            data = original.read(entry)
            if entry.filename == "modelDescription.xml":
                data = edit(data.decode()).encode()
            archive.writestr(entry, data)
    return copy


def test_variables_prepended_under_the_model_structure_are_refused_naming_the_entry(lag_fmu, tmp_path):
    extra = "".join(
        f'<ScalarVariable name="p{i}" valueReference="{1000 + i}" causality="local"><Real/></ScalarVariable>'
        for i in range(10_000)
    )
    shifted = _with_description(
        lag_fmu, tmp_path, lambda xml: xml.replace("<ModelVariables>", "<ModelVariables>" + extra)
    )
    with pytest.raises(
        InputError, match=r"Lag.fmu: modelDescription.xml: ModelStructure/Derivatives names 'p3', which"
    ):
        read_fmu(shifted)


def test_a_variable_declared_twice_is_refused_naming_it(lag_fmu, tmp_path):
    def duplicate_first(xml):
        first = re.search(r"<ScalarVariable .*?</ScalarVariable>", xml).group(0)
        return xml.replace(first, first + first)

    with pytest.raises(InputError, match=r"Lag.fmu: modelDescription.xml declares the variable\(s\) 'u' twice"):
        read_fmu(_with_description(lag_fmu, tmp_path, duplicate_first))


def test_an_output_index_naming_another_variable_is_refused(lag_fmu, tmp_path):
    swapped = _with_description(
        lag_fmu, tmp_path, lambda xml: xml.replace('<Unknown index="2" dep', '<Unknown index="5" dep')
    )
    with pytest.raises(InputError, match=r"ModelStructure/Outputs names 'T' of causality 'parameter'"):
        read_fmu(swapped)
    assert read_fmu(lag_fmu).states == ["y"]
