"""heliostep.scenario.tracking: the ``tracking`` and ``faults`` sections, each refusal naming its key."""

from __future__ import annotations

import pytest

from heliostep.errors import InputError
from heliostep.scenario import load_scenario


@pytest.mark.parametrize(
    ("overrides", "words"),
    [
        (("tracking.mode=closed_loop", "tracking.sensor=ssoc-d6"), ["tracking.sensor", "close: ssoc-d60"]),
        (("tracking.mode=sensor",), ["tracking.mode", "closed_loop"]),
        (("tracking.sample_period=1", "tracking.latency=1"), ["tracking.latency", "less than sample_period"]),
        (("faults.stuck=[30, 10]",), ["faults.stuck", "start < end"]),
        (("tracking.clouds=[{start: 10, end: 5}]",), ["tracking.clouds[0].end", "after start"]),
        (("tracking.sample_rate=1",), ["tracking.sample_rate"]),
    ],
)
def test_a_bad_tracking_or_fault_is_refused_naming_its_key(overrides, words):
    with pytest.raises(InputError) as raised:
        load_scenario("jan21-central", overrides)
    for word in words:
        assert word in str(raised.value), str(raised.value)


def test_a_loop_adds_the_sun_sensor_and_its_connection_and_open_loop_leaves_the_scenario_as_it_was():
    closed = load_scenario("jan21-central", ("tracking.mode=closed_loop",))
    assert closed.fmus["sensor"] == "SunSensor"
    assert ("mechanics.theta_p", "sensor.theta_p") in closed.connection_pairs()
    given = load_scenario("jan21-central", ("tracking.mode=hybrid", "connections=[[motor.tau, mechanics.tau]]"))
    assert given.connection_pairs() == [("motor.tau", "mechanics.tau"), ("mechanics.theta_p", "sensor.theta_p")]
    plain = load_scenario("jan21-central")
    assert "sensor" not in plain.fmus and not {"tracking", "faults"} & set(plain.resolved_dict())
