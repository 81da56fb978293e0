"""The ctypes mirror of the compiled kernel's structures and codes (heliostep.cosim.kernel) against
c/kernel.h as the C compiler lays it out: every size, field offset and code, read from the
compiled library's hs_describe."""

import ctypes

import pytest

import heliostep.cosim.kernel as kernel

STRUCTURES = kernel.STRUCTURES


@pytest.mark.parametrize("name", sorted(STRUCTURES))
def test_structure_size_and_field_offsets_match_the_c_side(name):
    structure = STRUCTURES[name]
    assert kernel.describe(name) == ctypes.sizeof(structure)
    for field, _ in structure._fields_:
        assert kernel.describe(f"{name}.{field}") == getattr(structure, field).offset, f"{name}.{field}"


def test_codes_match_the_c_side():
    codes = {name: getattr(kernel, name) for name in dir(kernel) if name.startswith("ADVANCE_")}
    assert len(codes) == 7
    for name, value in codes.items():
        assert kernel.describe(name) == value, name
    c_names = [
        "F_SET_TIME",
        "F_SET_STATES",
        "F_GET_REAL",
        "F_SET_REAL",
        "F_GET_DERIVATIVES",
        "F_GET_EVENT_INDICATORS",
        "F_GET_INTEGER",
        "F_GET_BOOLEAN",
    ]
    assert [kernel.describe(name) for name in c_names] == list(range(len(kernel.FUNCTIONS)))


def test_unknown_names_are_refused():
    assert kernel.describe("hs_kernel.no_such_field") == -1
