"""The hand-written third-party-style FMU BouncingBall on its own, with fmpy.

It is valid FMI 2.0 Model Exchange, its state events (impacts) and time event (kick)
match first principles when fmpy integrates it with CVODE, its input acts, and every
FMI call is checked against the state machine without crashing.  Built by the tests
(gcc), see ``third_party_fmu.py``.
"""

import ctypes
import math

import numpy as np
import pytest
from fmpy import calloc, extract, free, read_model_description, simulate_fmu
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import (
    FMU2Model,
    fmi2CallbackAllocateMemoryTYPE,
    fmi2CallbackFreeMemoryTYPE,
    fmi2CallbackFunctions,
    fmi2CallbackLoggerTYPE,
    fmi2CoSimulation,
    fmi2ModelExchange,
)
from fmpy.validation import validate_fmu

from third_party_fmu import VR, build_bouncing_ball

G, E, H0, KICK_DV = 9.81, 0.7, 1.0, 2.0
V_MIN = 0.1  # rebound speed below which the ball lies still (bouncing_ball.c)
V1 = math.sqrt(2 * G * H0)  # impact speed of the first impact
T1 = math.sqrt(2 * H0 / G)  # time of the first impact
NO_KICK = {"t_kick": 10.0}  # beyond every stop time used here


@pytest.fixture(scope="module")
def fmu(tmp_path_factory):
    return build_bouncing_ball(tmp_path_factory.mktemp("third_party_fmu"))


def simulate(fmu, stop_time=3.0, **kwargs):
    """fmpy's ME loop with CVODE; events are recorded (a row before and one after each)."""
    return simulate_fmu(
        str(fmu),
        fmi_type="ModelExchange",
        solver="CVode",
        stop_time=stop_time,
        output_interval=1e-3,
        relative_tolerance=1e-8,
        output=["h", "v", "height", "bounce_count"],
        **kwargs,
    )


def impacts(result):
    """Indices of the rows just before each increment of bounce_count."""
    steps = np.diff(result["bounce_count"])
    assert set(np.unique(steps)) <= {0.0, 1.0}, "bounce_count must count up by one"
    return np.nonzero(steps)[0]


# ------------------------------------------------------------------ the model description


def test_fmu_passes_fmpy_validation(fmu):
    assert validate_fmu(str(fmu)) == []


def test_model_description_declares_interface_states_and_events(fmu):
    description = read_model_description(str(fmu))
    assert description.fmiVersion == "2.0"
    assert description.modelExchange.modelIdentifier == "BouncingBall"
    assert description.coSimulation is None
    assert description.numberOfEventIndicators == 1
    variables = {v.name: v for v in description.modelVariables}
    assert {name: v.valueReference for name, v in variables.items()} == VR
    assert [v.name for v in description.modelVariables if v.causality == "input"] == ["f"]
    assert [v.name for v in description.modelVariables if v.causality == "output"] == ["height", "bounce_count"]
    assert variables["bounce_count"].variability == "discrete"
    assert {v.name: float(v.start) for v in description.modelVariables if v.causality == "parameter"} == {
        "g": G,
        "e": E,
        "h0": H0,
        "t_kick": 0.5,
    }
    assert [d.variable.derivative.name for d in description.derivatives] == ["h", "v"]
    assert variables["h"].unit == "m" and variables["der(v)"].unit == "m/s2"
    # no output depends directly on the input
    assert all(not any(d.causality == "input" for d in o.dependencies) for o in description.outputs)


# ------------------------------------------------------------------ state events: the bounces


def test_free_fall_and_bounces_match_first_principles(fmu):
    result = simulate(fmu, start_values=NO_KICK)
    t, h, v = result["time"], result["h"], result["v"]
    np.testing.assert_array_equal(result["height"], h)
    assert h.min() >= -1e-9, "the ball fell through the floor"

    # free fall until the first impact
    before = t < T1 - 1e-6
    np.testing.assert_allclose(h[before], H0 - G * t[before] ** 2 / 2, rtol=0, atol=1e-7)
    np.testing.assert_allclose(v[before], -G * t[before], rtol=0, atol=1e-7)

    rows = impacts(result)
    first = rows[0]
    assert t[first + 1] == t[first]  # the event is recorded before and after
    assert t[first] == pytest.approx(T1, abs=1e-6)
    assert h[first] == pytest.approx(0.0, abs=1e-9)
    assert v[first] == pytest.approx(-V1, rel=1e-6)
    assert (h[first + 1], v[first + 1]) == (0.0, pytest.approx(E * V1, rel=1e-6))
    assert result["bounce_count"][first] == 0 and result["bounce_count"][first + 1] == 1

    # up to the next apex e^2 h0: energy is conserved in flight, and the sampled parabola peaks there
    second = rows[1]
    flight = slice(first + 1, second + 1)
    energy = h[flight] + v[flight] ** 2 / (2 * G)
    np.testing.assert_allclose(energy, E**2 * H0, rtol=0, atol=1e-6 * H0)
    top = first + 1 + int(np.argmax(h[flight]))
    a, b, c = np.polyfit(t[top - 1 : top + 2] - t[top], h[top - 1 : top + 2], 2)
    assert c - b * b / (4 * a) == pytest.approx(E**2 * H0, abs=1e-6 * H0)
    assert t[top] - b / (2 * a) == pytest.approx(T1 + E * V1 / G, abs=1e-6)

    # every impact: times t_k = T1 + sum_{j<k} 2 e^j V1 / g, speeds e^(k-1) V1; at rest once
    # the rebound would be slower than V_MIN
    n_impacts = 1 + int(math.floor(math.log(V_MIN / V1) / math.log(E)))
    assert len(rows) == n_impacts == 11
    expected = T1 + np.concatenate([[0.0], np.cumsum(2 * E ** np.arange(1, n_impacts) * V1 / G)])
    np.testing.assert_allclose(t[rows], expected, rtol=0, atol=1e-5)  # integration errors add up
    np.testing.assert_allclose(v[rows], -V1 * E ** np.arange(n_impacts), rtol=0, atol=1e-5)
    np.testing.assert_array_equal(result["bounce_count"][rows + 1], np.arange(1, n_impacts + 1))
    rest = slice(rows[-1] + 1, None)
    assert np.all(h[rest] == 0.0) and np.all(v[rest] == 0.0)
    assert t[-1] == pytest.approx(3.0)


# ------------------------------------------------------------------ the time event: the kick


@pytest.mark.parametrize("t_kick", [0.2, None], ids=["t_kick=0.2", "default t_kick=0.5"])
def test_kick_time_event_adds_two_metres_per_second(fmu, t_kick):
    result = simulate(fmu, start_values={} if t_kick is None else {"t_kick": t_kick})
    t_kick = 0.5 if t_kick is None else t_kick
    t, h, v = result["time"], result["h"], result["v"]
    at = np.nonzero(np.isclose(t, t_kick, rtol=0, atol=1e-12))[0]
    assert len(at) == 2  # recorded before and after the event, exactly at t_kick
    before, after = at
    assert after == before + 1 and t[before] == t[after]
    assert h[after] == h[before]
    assert v[after] - v[before] == pytest.approx(KICK_DV, abs=1e-12)
    # smooth on either side of the jump
    assert v[before] - v[before - 1] == pytest.approx(-G * 1e-3, abs=1e-7)
    assert v[after + 1] - v[after] == pytest.approx(-G * 1e-3, abs=1e-7)
    if t_kick == 0.2:  # still in the first fall: everything follows in closed form
        h_kick, v_kick = H0 - G * t_kick**2 / 2, -G * t_kick + KICK_DV
        assert (h[after], v[after]) == (pytest.approx(h_kick, abs=1e-7), pytest.approx(v_kick, abs=1e-7))
        first_impact = t_kick + (v_kick + math.sqrt(v_kick**2 + 2 * G * h_kick)) / G
        assert t[impacts(result)[0]] == pytest.approx(first_impact, abs=1e-6)


def test_kick_wakes_a_ball_lying_on_the_floor(fmu):
    t_kick = 2.8  # the ball lies still from about 2.55 s on
    result = simulate(fmu, stop_time=3.5, start_values={"t_kick": t_kick})
    t, h, v, count = result["time"], result["h"], result["v"], result["bounce_count"]
    resting = (t > 2.6) & (t < t_kick)
    assert np.all(h[resting] == 0.0) and np.all(v[resting] == 0.0) and np.all(count[resting] == 11)
    flight = (t > t_kick) & (t < t_kick + 2 * KICK_DV / G - 1e-6)
    dt = t[flight] - t_kick
    np.testing.assert_allclose(h[flight], KICK_DV * dt - G * dt**2 / 2, rtol=0, atol=1e-7)
    landing = next(row for row in impacts(result) if t[row] > t_kick)
    assert t[landing] == pytest.approx(t_kick + 2 * KICK_DV / G, abs=1e-6)
    assert v[landing] == pytest.approx(-KICK_DV, rel=1e-6) and count[landing + 1] == 12


# ------------------------------------------------------------------ the input


@pytest.mark.parametrize("f", [G, G / 2])
def test_input_acceleration_acts_on_the_ball(fmu, f):
    signal = np.array([(0.0, f), (3.0, f)], dtype=[("time", np.float64), ("f", np.float64)])
    result = simulate(fmu, start_values=NO_KICK, input=signal)
    t, h, count = result["time"], result["h"], result["bounce_count"]
    if f == G:  # the input cancels gravity: the ball floats
        np.testing.assert_allclose(h, H0, rtol=0, atol=1e-12)
        np.testing.assert_allclose(result["v"], 0.0, rtol=0, atol=1e-12)
        assert np.all(count == 0)
    else:  # it falls with g - f
        first_impact = math.sqrt(2 * H0 / (G - f))
        falling = t < first_impact - 1e-6
        np.testing.assert_allclose(h[falling], H0 - (G - f) * t[falling] ** 2 / 2, rtol=0, atol=1e-7)
        assert t[impacts(result)[0]] == pytest.approx(first_impact, abs=1e-6)


# ------------------------------------------------------------------ the life cycle, call by call


class Host:
    """An FMU2Model instance with callbacks that record log messages and count allocations."""

    def __init__(self, fmu, unzip_dir, guid=None):
        self.messages = []
        self.live = set()
        self.n_allocations = 0
        description = read_model_description(str(fmu))
        self.callbacks = fmi2CallbackFunctions()
        self.callbacks.logger = fmi2CallbackLoggerTYPE(self._log)
        self.callbacks.allocateMemory = fmi2CallbackAllocateMemoryTYPE(self._allocate)
        self.callbacks.freeMemory = fmi2CallbackFreeMemoryTYPE(self._free)
        self.model = FMU2Model(
            guid=guid or description.guid, unzipDirectory=unzip_dir, modelIdentifier="BouncingBall", instanceName="ball"
        )

    def _log(self, env, instance, status, category, message):
        self.messages.append((status, category.decode(), message.decode()))

    def _allocate(self, nobj, size):
        pointer = calloc(nobj, size)
        self.live.add(pointer)
        self.n_allocations += 1
        return pointer

    def _free(self, pointer):
        if pointer:
            self.live.remove(pointer)
            free(pointer)

    def fails(self, call, *args, match):
        """``call(*args)`` must return fmi2Error and log a message containing ``match``."""
        self.messages.clear()
        with pytest.raises(FMICallException) as error:
            call(*args)
        assert error.value.status == 3  # fmi2Error
        assert any(match in message and status == 3 for status, _, message in self.messages), self.messages


@pytest.fixture
def unzip_dir(fmu, tmp_path):
    return extract(str(fmu), unzipdir=str(tmp_path / "unzipped"))


def test_life_cycle_rejects_wrong_calls_without_crashing(fmu, unzip_dir):
    host = Host(fmu, unzip_dir)
    model = host.model
    model.instantiate(callbacks=host.callbacks)
    assert host.live and host.messages == []  # memory from the callbacks; nothing to report

    # calls in the wrong state
    host.fails(model.newDiscreteStates, match="illegal call sequence")
    host.fails(model.exitInitializationMode, match="illegal call sequence")
    host.fails(model.getReal, [VR["h"]], match="illegal call sequence")
    # invalid value references and values; a failing set changes nothing
    host.fails(model.setReal, [VR["g"], 99], [1.0, 2.0], match="invalid value reference 99")
    host.fails(model.setReal, [VR["height"]], [2.0], match="cannot be set")
    host.fails(model.setReal, [VR["e"]], [1.5], match="out of range")
    host.fails(model.setReal, [VR["h0"]], [float("nan")], match="not finite")
    host.fails(model.setInteger, [0], [1], match="invalid value reference 0")

    model.setReal([VR["h0"], VR["t_kick"]], [2.0, 0.25])
    model.setupExperiment(startTime=0.0)
    model.enterInitializationMode()
    host.fails(model.setupExperiment, match="illegal call sequence")
    host.fails(model.getReal, [VR["bounce_count"] + 1], match="invalid value reference 12")
    assert model.getReal([VR["g"], VR["h"], VR["height"]]) == [G, 2.0, 2.0]
    model.exitInitializationMode()
    assert model.newDiscreteStates() == (False, False, False, False, True, 0.25)  # the time event
    model.enterContinuousTimeMode()
    host.fails(model.setReal, [VR["g"]], [1.0], match="cannot be set in Continuous-Time Mode")
    host.fails(model.newDiscreteStates, match="illegal call sequence")
    host.fails(model.getFMUstate, match="not supported")
    host.fails(model.getDirectionalDerivative, [VR["der(v)"]], [VR["v"]], [1.0], match="not supported")

    # the instance still works
    x, dx, z = (np.zeros(n) for n in (2, 2, 1))
    for array, call in ((x, model.getContinuousStates), (dx, model.getDerivatives), (z, model.getEventIndicators)):
        call(array.ctypes.data_as(ctypes.POINTER(ctypes.c_double)), array.size)
    assert (x.tolist(), dx.tolist(), z.tolist()) == ([2.0, 0.0], [0.0, -G], [2.0])
    host.fails(model.getDerivatives, dx.ctypes.data_as(ctypes.POINTER(ctypes.c_double)), 3, match="nx = 3")
    model.setReal([VR["f"]], [1.0])  # inputs may change in continuous time
    model.setTime(0.25)
    model.enterEventMode()
    assert model.newDiscreteStates() == (False, False, False, True, False, 0.0)  # the kick
    assert model.getReal([VR["v"]]) == [KICK_DV]
    model.terminate()
    host.fails(model.enterEventMode, match="illegal call sequence")
    model.reset()
    model.enterInitializationMode()
    assert model.getReal([VR["h"], VR["t_kick"]]) == [H0, 0.5]
    model.exitInitializationMode()
    model.terminate()
    model.fmi2FreeInstance(model.component)
    assert not host.live and host.n_allocations >= 2  # everything freed through the callbacks


def test_instantiate_checks_guid_and_interface_type(fmu, unzip_dir):
    host = Host(fmu, unzip_dir, guid="{00000000-0000-0000-0000-000000000000}")
    with pytest.raises(Exception, match="Failed to instantiate"):
        host.model.instantiate(callbacks=host.callbacks)
    assert any("wrong GUID" in message for _, _, message in host.messages)

    host = Host(fmu, unzip_dir)
    resources = f"file://{unzip_dir}/resources".encode()
    component = host.model.fmi2Instantiate(
        b"cs", fmi2CoSimulation, host.model.guid.encode(), resources, ctypes.byref(host.callbacks), 0, 0
    )
    assert component is None
    assert any("Model Exchange only" in message for _, _, message in host.messages)
    component = host.model.fmi2Instantiate(
        b"me", fmi2ModelExchange, host.model.guid.encode(), resources, ctypes.byref(host.callbacks), 0, 0
    )
    assert component is not None
    with pytest.raises(FMICallException):  # a NULL instance is refused, not dereferenced
        host.model.fmi2Terminate(None)
    host.model.fmi2FreeInstance(None)
    host.model.fmi2FreeInstance(component)
    assert not host.live
