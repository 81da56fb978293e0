"""The co-simulated pull-out torque of the Applied Motion HT34-504 against its measured curve.

Measured (marcozorzi/Bachelor-Thesis, commit ac1e5af, mat/HT34_v1.m: ``pullout_speed_or = 0:150:1800``
[rpm], ``pullout_torque_or`` [N.m]; a thesis, not Applied Motion; bus and drive not stated), at the
rates tested here: 2.69 N.m at 500 full steps/s (150 rpm, the plateau), 1.91 at 1 500, 0.96 at 3 000,
0.32 at 6 000. The motor: 7.56 A, 2.80 N.m holding torque, 1 100 g.cm2 (Applied Motion, STR hardware
manual 920-0030E), L = 1.7 mH (the thesis); R and the detent torque are bands, the bus 24-75 V
(tests/support/measured_pull_out.py). Two phases on, full steps, at 7.56 A.

The band: its bottom the smaller of the two corners' pull-out on 24 V, its top the larger on 75 V. The
bisection finds a load the rotor carries, within 2 % of the holding torque (0.056 N.m) below the true
pull-out. Nothing is fitted to the measured curve: where it leaves the band the gap is stated.
"""

from __future__ import annotations

import math

import pytest

from heliostep.run.load_budget import static_step_limit
from heliostep.run.speed_torque import pull_out_torque
from measured_pull_out import MEASURED_PLATEAU, MODE, RATED_CURRENT, band_corners, measured_at

RATES = (500.0, 1500.0, 3000.0, 6000.0)  # [full steps/s]
TOLERANCE = 0.02  # of the two-phase holding torque
#: The bisection's resolution [N.m]: TOLERANCE of the largest two-phase holding torque, 2.79 N.m.
RESOLUTION = TOLERANCE * math.sqrt(2.0) * band_corners(75.0)["high"].holding_torque(RATED_CURRENT)


@pytest.fixture(scope="module")
def band(fmu_paths):
    """(bus [V], corner) -> rate -> co-simulated pull-out torque [N.m], on 24 and 75 V."""
    fmus = {"motor": fmu_paths["StepperMotor"], "mechanics": fmu_paths["PanelMechanics"]}
    return {
        (bus, corner): {
            rate: pull_out_torque(drive, RATED_CURRENT, rate, mode=MODE, tolerance=TOLERANCE, fmus=fmus)
            for rate in RATES
        }
        for bus in (24.0, 75.0)
        for corner, drive in band_corners(bus).items()
    }


def edges(band, rate):
    """The band's bottom (24 V) and top (75 V) at ``rate`` [N.m]."""
    bottom = min(band[24.0, corner][rate] for corner in ("low", "high"))
    top = max(band[75.0, corner][rate] for corner in ("low", "high"))
    return bottom, top


def test_the_plateau_lies_above_the_band_as_full_steps_say(band):
    # two phases on, full steps: the rotor in continuous motion carries the mean of its torque over a
    # step, between the static step limit (a step from rest against a static load, sqrt(2) T sin(pi/4)
    # = 1.97 N.m) and the peak sqrt(2) k_e I K / (K + R) = 2.78-2.79 N.m; co-simulated 2.30-2.31 N.m, 0.83
    # of the peak. The measured plateau, 2.69 N.m = 0.96 of the holding torque, is what a drive with a
    # smooth (microstepped) current reaches: 0.38 N.m above the band's top, 16 %
    drive = band_corners(75.0)["high"]
    peak = math.sqrt(2.0) * drive.holding_torque(RATED_CURRENT)
    bottom, top = edges(band, 500.0)
    assert static_step_limit(drive, RATED_CURRENT, MODE) < bottom <= top < measured_at(500.0) < peak
    assert measured_at(500.0) == MEASURED_PLATEAU
    assert measured_at(500.0) - top == pytest.approx(0.38, abs=0.06)


def test_the_measured_fall_lies_inside_the_band_by_1500_steps_per_s(band):
    # where the bus decides: 1.91 N.m measured between 24 V's 1.35-1.48 N.m and 75 V's 2.30-2.31 N.m (on
    # 24 V the current needs L I / V = 0.54 ms to rise, four fifths of the 0.67 ms step; on 75 V 0.17)
    bottom, top = edges(band, 1500.0)
    assert bottom + RESOLUTION < measured_at(1500.0) < top


def test_at_3000_steps_per_s_the_measured_point_is_on_the_bands_24_volt_edge(band):
    # 0.96 N.m measured, 0.91-0.92 co-simulated on 24 V: equal within the bisection's resolution; 75 V's
    # 2.09-2.14 N.m, more than twice it (the back-EMF, k_e omega = 24.6 V at 3000 steps/s, equals the
    # 24 V bus; on 75 V it is a third of it)
    bottom, top = edges(band, 3000.0)
    assert measured_at(3000.0) == pytest.approx(bottom, abs=2 * RESOLUTION)
    assert top > 2.0 * measured_at(3000.0)


def test_at_6000_steps_per_s_the_band_lies_above_the_measured_point_on_every_bus(band):
    # 0.32 N.m measured; co-simulated 0.43-0.44 on 24 V (the band's bottom), 1.22-1.26 on 75 V: the model
    # is optimistic by 0.115 N.m, 36 %, at the lowest bus of the range and more at any higher one, so
    # no bus in 24-75 V closes the gap. What the model leaves out grows with speed: iron losses
    # (G_m = 0, no source) brake the rotor by k_e^2 G_m omega; the missing 0.115 N.m at omega = 188 rad/s
    # is 22 W
    bottom, top = edges(band, 6000.0)
    for corner in ("low", "high"):
        assert band[75.0, corner][6000.0] > band[24.0, corner][6000.0]
    assert bottom - measured_at(6000.0) == pytest.approx(0.115, abs=0.03)
    assert bottom > 1.3 * measured_at(6000.0)
