"""Motor catalogue entries the sizing tests build their catalogues from, each value from the datasheet it names."""

from __future__ import annotations

#: TRINAMIC QSH8618-65-59-340 (QMot QSH8618 manual V1.08, Table 2.1), tried at 3 A only.
QSH8618_65_AT_3A = {
    "manufacturer": "TRINAMIC Motion Control (QMot)",
    "model": "QSH8618-65-59-340",
    "datasheet": "QMot QSH8618 manual V1.08, Table 2.1",
    "holding_torque": 3.4,
    "rated_current": 5.9,
    "resistance": 0.28,
    "inductance": 1.7e-3,
    "rotor_inertia": 1.0e-4,
    "detent_torque": 0.078,
    "step_angle": 1.8,
    "bus_voltage": 48.0,
    "currents": [3.0],
}
