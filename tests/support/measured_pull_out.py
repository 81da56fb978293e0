"""A measured NEMA 34 pull-out curve and the motor's known values, for comparing the co-simulated curve.

The motor: Applied Motion Products HT34-504, parallel wiring. Its rating, 7.56 A per phase, 396 oz-in =
2.80 N.m holding torque (two phases on) and 1 100 g.cm2 rotor inertia, is Applied Motion's (STR hardware
manual 920-0030E, the motor table). The pull-out curve and the phase inductance are secondary: the
public repository marcozorzi/Bachelor-Thesis (a bachelor thesis), commit ac1e5af, mat/HT34_v1.m
(``pullout_speed_or = 0:150:1800`` [rpm], ``pullout_torque_or`` [N.m]; ``Jm = 1.1e-4``) and
mat/HT34_v5.m (``L_mot = 1.7``, labelled [H]: a NEMA 34 winding for 7.56 A has millihenries, so 1.7 mH).
The curve's bus voltage and drive are not stated; Applied Motion's drives for this motor run on 24-75 V.
The phase resistance and the detent torque are in no source read here: they are bands (below).
"""

from __future__ import annotations

import math

from heliostep.scenario.catalogue import MotorDrive

#: The measured pull-out curve [rpm] -> [N.m] (mat/HT34_v1.m), 0 to 1 800 rpm every 150 rpm.
MEASURED_RPM = tuple(range(0, 1801, 150))
MEASURED_TORQUE = (2.69, 2.69, 2.69, 1.91, 1.27, 1.06, 0.96, 0.85, 0.74, 0.64, 0.53, 0.42, 0.32)
#: Its plateau [N.m]: the torque from 0 to 300 rpm (0 to 1 000 full steps/s).
MEASURED_PLATEAU = 2.69

#: The motor (parallel): rated current [A], holding torque two phases on [N.m], rotor inertia [kg.m2],
#: phase inductance [H], full steps per turn (1.8 deg: N_c = 50 rotor teeth).
RATED_CURRENT = 7.56
HOLDING_TORQUE = 396 * 0.00706155  # 396 oz-in = 2.796 N.m
ROTOR_INERTIA = 1.1e-4
INDUCTANCE = 1.7e-3
STEPS_PER_TURN = 200

#: The phase resistance's band [Ohm]: the shipped catalogue's NEMA 34 entries (TRINAMIC QSH8618-65, -80,
#: -118, -156: R = 0.28, 0.42, 0.45, 0.75 Ohm at 5.9, 5.5, 6.0, 6.2 A), each scaled to the same copper
#: loss R I^2 at its rated current (a winding for a larger current in the same frame has fewer turns of a
#: thicker wire, R ~ 1/I^2), min and max: 0.28 (5.9 / 7.56)^2 = 0.171, 0.75 (6.2 / 7.56)^2 = 0.504.
CATALOGUE_NEMA34 = ((0.28, 5.9), (0.42, 5.5), (0.45, 6.0), (0.75, 6.2))
RESISTANCE_BAND = (
    min(r * (i / RATED_CURRENT) ** 2 for r, i in CATALOGUE_NEMA34),
    max(r * (i / RATED_CURRENT) ** 2 for r, i in CATALOGUE_NEMA34),
)
#: The detent torque's band [N.m]: the catalogue's ratio to the holding torque, 2.3-2.8 % (TRINAMIC
#: QSH8618 manual V1.08, Table 2.1, as models/StepperMotor.mo cites).
DETENT_BAND = (0.023 * HOLDING_TORQUE, 0.028 * HOLDING_TORQUE)
#: The drive: two phases on at the rated current (the datasheet's holding torque is two phases on, and the
#: measured plateau, 2.69 N.m = 0.96 of it, is above the sqrt(2) smaller peak one phase on or sine/cosine
#: microsteps at 7.56 A give); the buses [V] of Applied Motion's drives for the motor, 24-75 V.
MODE = "two-phase-on"
BUSES = (24.0, 48.0, 75.0)


def full_steps_per_s(rpm: float) -> float:
    """The full-step rate [steps/s] of ``rpm`` [1/min] (1.8 deg: 200 full steps per turn)."""
    return rpm / 60.0 * STEPS_PER_TURN


def measured_at(step_rate: float) -> float:
    """The measured pull-out torque [N.m] at a measured point's ``step_rate`` [full steps/s]."""
    rates = [full_steps_per_s(rpm) for rpm in MEASURED_RPM]
    return MEASURED_TORQUE[rates.index(step_rate)]


def ht34_drive(resistance: float, bus_voltage: float, detent_torque: float) -> MotorDrive:
    """The HT34-504 as the motor FMU sees it: k_e = T_hold / (sqrt(2) I), L, J_m, N_c = 50."""
    return MotorDrive(
        resistance=resistance,
        inductance=INDUCTANCE,
        torque_constant=HOLDING_TORQUE / (math.sqrt(2.0) * RATED_CURRENT),
        rotor_teeth=STEPS_PER_TURN / 4,
        bus_voltage=bus_voltage,
        rotor_inertia=ROTOR_INERTIA,
        detent_torque=detent_torque,
    )


def band_corners(bus_voltage: float) -> dict[str, MotorDrive]:
    """The drive at ``bus_voltage`` [V] with the weakest (largest R and detent) and strongest values."""
    return {
        "low": ht34_drive(RESISTANCE_BAND[1], bus_voltage, DETENT_BAND[1]),
        "high": ht34_drive(RESISTANCE_BAND[0], bus_voltage, DETENT_BAND[0]),
    }
