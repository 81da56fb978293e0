"""Issue #24: FMI 3.0 Model Exchange with every variable type and array variables.

Types3 (``tests/data/mini3/types3.c``, built by ``tests/support/types3_fmu.py``) passes every FMI 3.0
type through (T_out = T_in), a 2 x 3 Float64 array (a_out = a_in + offset) and has generators:
states x (Float64 [2]) with der(x) = rates, an Int8 counter count8 (count8_start + one per time
event k * period, wrapping as an Int8 does), a Float32 ramp32 = float32(slope * t), a String
tick_text = "<greeting> <count8>" and a Binary tick_bytes = count8 as a byte and tag (greeting, a
String parameter, "tick"; tag, a Binary parameter, {0xA5}).

Alone it is compared with fmpy's own FMI 3.0 simulation (``fmpy.simulate_fmu``, fmi_type
ModelExchange) and with first principles; connected to itself, to the FMI 3.0 Counter3 and to
FMI 2.0 mini FMUs, with first principles computed here with numpy (an Int8 wrapping, a Float64
rounded to Float32 by numpy.float32, an array's elements by their names, a String and a Binary
passed through and reported).
"""

from __future__ import annotations

import numpy as np
import pytest

import heliostep.cosim.integrator as integrator
from heliostep.cosim import Connection, CoSimulation, SolverOptions, read_fmu
from heliostep.cosim.connections import ConnectionGraph
from heliostep.errors import InputError
from third_party_fmu import build_mini_fmu
from third_party_fmu3 import build_mini3_fmu
from types3_fmu import build_types3_fmu

PERIOD, START8 = 0.25, 125


@pytest.fixture(scope="module")
def fmus(tmp_path_factory):
    out = tmp_path_factory.mktemp("fmi3types")
    return {
        "Types3": build_types3_fmu(out),
        "Counter3": build_mini3_fmu("Counter3", out),
        "Gain": build_mini_fmu("Gain", out),
        "PassThrough": build_mini_fmu("PassThrough", out),
    }


def wrapped_int8(value):
    """An integer as an Int8 holds it (two's complement): 127 + 1 = -128."""
    return (np.asarray(value, dtype=np.int64) + 128) % 256 - 128


def test_types3_alone_agrees_with_fmpy_for_every_type_and_names_the_array_elements(fmus):
    import fmpy

    parameters = {"count8_start": START8, "slope": 0.3, "offset[2,1]": -7.5, "rates[2]": 2.0}
    parameters |= {"greeting": "step", "tag": "5a0b"}  # a String and a Binary parameter (hexadecimal digits)
    system = CoSimulation({"s": read_fmu(fmus["Types3"])}, [], parameters={"s": parameters})
    result = system.simulate(0.0, 1.0, np.linspace(0.0, 1.0, 5), SolverOptions(rtol=1e-9))
    offset = [11.0, 12.0, 13.0, -7.5, 22.0, 23.0]
    reference = fmpy.simulate_fmu(
        str(fmus["Types3"]),
        fmi_type="ModelExchange",
        stop_time=1.0,
        output_interval=0.25,
        relative_tolerance=1e-9,
        start_values={"count8_start": START8, "slope": 0.3, "offset": offset, "rates": [1.0, 2.0]},
    )
    assert result.statistics["compiled_rhs"] is True  # every type traced by the compiled kernel
    trace = result.trace.drop_duplicates("time", keep="last").reset_index(drop=True)
    mine = reference[np.r_[np.diff(reference["time"]) > 0, True]]  # fmpy's rows after each event
    np.testing.assert_array_equal(trace["time"], mine["time"])
    t = trace["time"].to_numpy()
    # elements named 1-based, row-major: a_out[i,j] is fmpy's a_out[:, i-1, j-1]
    for i, j in np.ndindex(2, 3):
        np.testing.assert_array_equal(trace[f"s.a_out[{i + 1},{j + 1}]"], mine["a_out"][:, i, j])
    assert (trace["s.a_out[2,1]"] == -7.5).all() and (trace["s.a_out[1,3]"] == 13.0).all()
    for k, rate in enumerate((1.0, 2.0)):
        np.testing.assert_allclose(trace[f"s.x[{k + 1}]"], mine["x"][:, k], rtol=1e-9)
        np.testing.assert_allclose(trace[f"s.x[{k + 1}]"], rate * t, rtol=1e-9)
    scalars = ["count8", "ramp32"] + [f"{kind}_out" for kind in ("Float32", "Float64", "Int8", "UInt8", "Int16")]
    scalars += [f"{kind}_out" for kind in ("UInt16", "Int32", "UInt32", "Int64", "UInt64", "Boolean", "Enumeration")]
    for name in scalars:
        np.testing.assert_array_equal(trace[f"s.{name}"], mine[name].astype(float), err_msg=name)
    # first principles: an Int8 counter wraps at 127; a Float32 product rounded as numpy rounds it
    ticks = np.floor(t / PERIOD + 1e-9)
    np.testing.assert_array_equal(trace["s.count8"], wrapped_int8(START8 + ticks))
    assert list(trace["s.count8"]) == [125, 126, 127, -128, -127]
    np.testing.assert_array_equal(trace["s.ramp32"], np.float32(np.float64(np.float32(0.3)) * t))
    texts = result.statistics["text_outputs"]
    assert texts["s.tick_text"] == [[tk, f"step {c}"] for tk, c in zip(t, wrapped_int8(START8 + ticks))]
    assert texts["s.tick_bytes"] == [[tk, bytes([int(c) % 256, 0x5A, 0x0B]).hex()] for tk, c in zip(t, START8 + ticks)]
    assert texts["s.String_out"] == [[0.0, "none"]] and texts["s.Binary_out"] == [[0.0, "a5"]]


#: Types3 "src" generates, Types3 "thru" passes through; FMI 3.0 Counter3 "c" counts; FMI 2.0 Gain
#: "ramp" gives s = t / 3; FMI 2.0 PassThrough "p" receives FMI 3.0 values.
SYSTEM = {"src": "Types3", "thru": "Types3", "c": "Counter3", "ramp": "Gain", "p": "PassThrough"}
CONNECTIONS = [
    ("ramp.s", "thru.Float32_in"),  # FMI 2.0 Real -> Float32: rounded
    ("src.ramp32", "p.u_c"),  # Float32 -> FMI 2.0 Real
    ("src.x[2]", "thru.Float64_in"),  # an array element -> a scalar
    ("src.x[1]", "thru.a_in[1,2]"),  # a scalar into one element of an array
    ("src.count8", "thru.Int8_in"),
    ("thru.Int8_out", "p.u_i"),  # Int8 -> FMI 2.0 Integer
    ("c.count", "thru.Int64_in"),  # Int32 -> Int64
    ("c.odd", "thru.Boolean_in"),
    ("thru.Boolean_out", "p.u_b"),  # FMI 3.0 Boolean -> FMI 2.0 Boolean
    ("src.tick_text", "thru.String_in"),
    ("src.tick_bytes", "thru.Binary_in"),
    ("src.Enumeration_out", "thru.Enumeration_in"),
]


def run_system(fmus, stop=2.0):
    system = CoSimulation(
        {name: read_fmu(fmus[kind]) for name, kind in SYSTEM.items()},
        [Connection(*c) for c in CONNECTIONS],
        parameters={
            "src": {"count8_start": START8},
            "c": {"t_stop": 100.0},
            "ramp": {"k": 0.0, "b": 1.0 / 3.0},
        },
    )
    return system.simulate(0.0, stop, np.linspace(0.0, stop, 9), SolverOptions(rtol=1e-9))


def check_connected(result):
    trace = result.trace.drop_duplicates("time", keep="last")
    t = trace["time"].to_numpy()
    s = trace["ramp.s"].to_numpy()
    np.testing.assert_allclose(s, t / 3.0, rtol=1e-9)
    np.testing.assert_array_equal(trace["thru.Float32_out"], s.astype(np.float32))  # numpy's rounding
    assert (trace["thru.Float32_out"] != s)[t > 0].all()  # t / 3 is no Float32: the rounding is seen
    np.testing.assert_array_equal(trace["p.y_c"], np.float32(np.float64(np.float32(0.1)) * t))
    np.testing.assert_allclose(trace["thru.Float64_out"], -0.5 * t, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(trace["thru.a_out[1,2]"], t + 12.0, rtol=1e-9)
    assert (trace["thru.a_out[1,1]"] == 11.0).all() and (trace["thru.a_out[2,3]"] == 23.0).all()
    ticks = np.floor(t / PERIOD + 1e-9)
    np.testing.assert_array_equal(trace["thru.Int8_out"], wrapped_int8(START8 + ticks))
    np.testing.assert_array_equal(trace["p.y_i"], wrapped_int8(START8 + ticks))
    assert trace["p.y_i"].max() == 127 and trace["p.y_i"].min() == -128  # it wrapped
    np.testing.assert_array_equal(trace["thru.Int64_out"], np.floor(t))
    np.testing.assert_array_equal(trace["p.y_b"], np.floor(t) % 2)
    np.testing.assert_array_equal(trace["thru.Enumeration_out"], 1.0)
    texts = result.statistics["text_outputs"]
    assert texts["thru.String_out"] == texts["src.tick_text"]
    assert [v for _, v in texts["thru.String_out"]] == [f"tick {c}" for c in wrapped_int8(START8 + np.arange(9))]
    assert texts["thru.Binary_out"] == [[tk, bytes([int(c) % 256, 0xA5]).hex()] for tk, c in zip(t, START8 + ticks)]


def test_fmi3_types_and_array_elements_connected_with_fmi2_follow_first_principles(fmus):
    result = run_system(fmus)
    assert result.statistics["compiled_rhs"] is True  # Float32 and array elements through the adapter's slots
    check_connected(result)


def test_on_the_python_right_hand_side_the_typed_system_gives_the_same(fmus, monkeypatch):

    monkeypatch.setattr(integrator, "compiled_kernel", lambda *args: None)
    result = run_system(fmus)
    assert result.statistics["compiled_rhs"] is False
    check_connected(result)


@pytest.mark.parametrize(
    "source, target, words",
    [
        ("thru.Int64_out", "p.u_i", ["cannot hold every value", "Int64 (FMI 3.0)", "is Integer"]),
        ("src.UInt8_out", "thru.Int8_in", ["cannot hold every value", "UInt8 (FMI 3.0)", "Int8 (FMI 3.0)"]),
        ("thru.String_out", "p.u_c", ["types are incompatible", "String (FMI 3.0)", "is Real"]),
        ("src.ramp32", "thru.Int32_in", ["types are incompatible", "Float32 (FMI 3.0)", "Int32 (FMI 3.0)"]),
        ("src.tick_bytes", "thru.String_in", ["types are incompatible", "Binary (FMI 3.0)", "String (FMI 3.0)"]),
    ],
)
def test_incompatible_fmi3_connections_are_refused_naming_both_ends(fmus, source, target, words):
    infos = {name: read_fmu(fmus[kind]) for name, kind in SYSTEM.items()}
    with pytest.raises(InputError) as refused:
        ConnectionGraph(infos, [Connection(source, target)])
    message = str(refused.value)
    assert f"{source} -> {target}" in message and all(word in message for word in words), message


def test_a_parameter_outside_its_fmi3_types_range_is_an_input_error_naming_it(fmus):
    with pytest.raises(InputError, match=r"count8_start: 128 is not a valid Int8 value"):
        system = CoSimulation({"s": read_fmu(fmus["Types3"])}, [], parameters={"s": {"count8_start": 128}})
        system.simulate(0.0, 0.5, np.linspace(0.0, 0.5, 3), SolverOptions())


def test_types3_beside_the_shipped_drive_writes_its_elements_by_name_and_its_text_outputs(tmp_path, fmus):
    import json

    import pandas as pd

    from heliostep.cli import main
    from heliostep.paths import scenarios_dir

    out = tmp_path / "out"
    args = ["run", str(scenarios_dir() / "jan21-central.yaml"), "--out", str(out), "--no-plots"]
    assert main([*args, "--set", "window.duration=3", "--set", f"fmus.types={fmus['Types3']}"]) == 0
    trace = pd.read_parquet(out / "trace.parquet").drop_duplicates("time", keep="last")
    t = trace["time"].to_numpy()
    elements = [f"types.a_out[{i},{j}]" for i in (1, 2) for j in (1, 2, 3)]
    assert [c for c in trace.columns if c.startswith("types.a_out")] == elements  # row-major, 1-based
    assert (trace["types.a_out[2,1]"] == 21.0).all() and (trace["types.a_out[1,3]"] == 13.0).all()
    np.testing.assert_array_equal(trace["types.count8"], wrapped_int8(120 + np.floor(t / PERIOD + 1e-9)))
    np.testing.assert_allclose(trace["types.x[2]"], -0.5 * t, rtol=1e-9, atol=1e-12)
    texts = json.loads((out / "metadata.json").read_text())["statistics"]["text_outputs"]
    assert texts["types.tick_text"][-1] == [3.0, f"tick {wrapped_int8(120 + 12)}"]  # 132 as an Int8: -124
    assert texts["types.tick_bytes"][-1] == [3.0, bytes([132, 0xA5]).hex()]
