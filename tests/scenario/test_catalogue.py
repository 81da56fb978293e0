"""The shipped motor catalogue (issue 57): frames, makers, a source on every entry, the optional keys."""

from __future__ import annotations

import math

import pytest

from heliostep.errors import InputError
from heliostep.scenario.catalogue import close_names, load_catalogue, shipped_catalogue_path


def test_the_shipped_catalogue_loads_with_a_source_on_every_entry():
    candidates = load_catalogue()
    assert len(candidates) >= 8
    assert len({c.manufacturer for c in candidates}) >= 2  # TRINAMIC, Beckhoff (a third maker: not yet)
    for c in candidates:
        assert c.datasheet.strip() and c.model.strip()
        assert c.currents[-1] <= c.rated_current  # size tries currents up to the rated one
        assert c.drive().rotor_teeth == pytest.approx(50.0)  # every entry: 1.8 deg


def test_the_shipped_catalogue_spans_nema_17_to_34():
    frames = {c.frame for c in load_catalogue() if c.frame}
    assert {"NEMA 17", "NEMA 23", "NEMA 34"} <= frames


def test_datasheet_values_as_written_in_si_units():
    """Two entries against their datasheet tables (QMot QSH4218 manual V1.10, Table 2.1; Beckhoff AS1060's
    technical data): g.cm2 -> kg.m2, mN.m -> N.m, mH -> H."""
    by_name = {c.name: c for c in load_catalogue()}
    small = by_name["QSH4218-51-10-049"]
    assert (small.holding_torque, small.rated_current, small.resistance) == (0.49, 1.0, 5.0)
    assert small.inductance == pytest.approx(8.0e-3) and small.rotor_inertia == pytest.approx(68e-7)
    assert small.detent_torque == pytest.approx(28e-3) and small.test_voltage == 24.0
    large = by_name["AS1060-xxxx"]
    assert (large.holding_torque, large.rated_current, large.resistance) == (5.0, 5.0, 0.36)
    assert large.rotor_inertia == pytest.approx(3.0e-4) and large.frame is None and large.test_voltage is None
    assert large.torque_constant == pytest.approx(5.0 / (math.sqrt(2.0) * 5.0))


def test_an_unknown_name_lists_close_names():
    with pytest.raises(InputError) as raised:
        load_catalogue(None, ["QSH4218-51"])
    message = str(raised.value)
    assert str(shipped_catalogue_path()) in message and "'QSH4218-51'" in message
    assert "close: QSH4218-51-10-049" in message
    assert close_names("as1060", ["AS1060-xxxx", "QSH5718-76-28-189"]) == ["AS1060-xxxx"]


def test_an_unknown_optional_value_is_refused(tmp_path):
    text = shipped_catalogue_path().read_text().replace("    test_voltage: 24.0\n", "    test_voltage: -1\n", 1)
    path = tmp_path / "motors.yaml"
    path.write_text(text)
    with pytest.raises(InputError, match=r"motors\.QSH4218-35-10-027\.test_voltage: expected > 0"):
        load_catalogue(path)
