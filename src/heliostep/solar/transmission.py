"""The rack-and-pinion transmission between rotor and panel ([paper], eqs. 12-15)."""

from __future__ import annotations

import numpy as np

from heliostep.errors import InputError
from heliostep.solar.checks import (
    as_float_array,
    check_positive,
    series_template,
    wrap_like,
)

#: Pinion radius of the secondary drive in the paper [m].
PAPER_PINION_RADIUS = 2.5e-3
#: Lever arm of the panel on the rack in the paper [m].
PAPER_LEVER_ARM = 0.3


# --------------------------------------------------------------------------- transmission
def _check_transmission(pinion_radius, lever_arm):
    return (
        check_positive(pinion_radius, "pinion_radius", "m"),
        check_positive(lever_arm, "lever_arm", "m"),
    )


def _check_panel_angle(values, name):
    array = as_float_array(values)
    if not np.all(np.isfinite(array)) or np.any(np.abs(array) >= np.pi / 2):
        raise InputError(f"{name} must be finite and within (-pi/2, pi/2) rad")
    return array


def rotor_angle_from_panel(panel_angle, panel_angle0, pinion_radius, lever_arm, rotor_angle0=0.0):
    """Rotor angle of the secondary stepper that sets a panel angle (rack and pinion).

    Parameters
    ----------
    panel_angle : array-like or Series  [rad]
    panel_angle0 : float  [rad]
        Panel angle when the rotor is at ``rotor_angle0``.
    pinion_radius : float  [m]
        r, > 0 (paper: 2.5e-3).
    lever_arm : float  [m]
        s, > 0 (paper: 0.3).
    rotor_angle0 : float, default 0  [rad]

    Returns
    -------
    array or Series  [rad]
        theta = theta0 + (s / r) (tan(panel_angle) - tan(panel_angle0)).
    """
    radius, arm = _check_transmission(pinion_radius, lever_arm)
    panel = _check_panel_angle(panel_angle, "panel_angle")
    panel0 = _check_panel_angle(panel_angle0, "panel_angle0")
    rotor_angle0 = as_float_array(rotor_angle0)
    # rack travel: r (theta - theta0)  # [paper], eq. 12
    # rack travel: s (tan(panel) - tan(panel0))  # [paper], eq. 13; equal, hence eq. 14:
    rotor = rotor_angle0 + arm / radius * (np.tan(panel) - np.tan(panel0))  # [paper], eq. 14
    return wrap_like(rotor, series_template(panel_angle), "rotor_angle")


def panel_angle_from_rotor(rotor_angle, panel_angle0, pinion_radius, lever_arm, rotor_angle0=0.0):
    """Panel angle set by a rotor angle of the secondary stepper (inverse of eq. 14).

    Parameters
    ----------
    rotor_angle : array-like or Series  [rad]
    panel_angle0 : float  [rad]
        Panel angle when the rotor is at ``rotor_angle0``.
    pinion_radius : float  [m]
    lever_arm : float  [m]
    rotor_angle0 : float, default 0  [rad]

    Returns
    -------
    array or Series  [rad]
        arctan(tan(panel_angle0) + (r / s) (theta - theta0)).
    """
    radius, arm = _check_transmission(pinion_radius, lever_arm)
    panel0 = _check_panel_angle(panel_angle0, "panel_angle0")
    rotor = as_float_array(rotor_angle)
    panel = np.arctan(np.tan(panel0) + radius / arm * (rotor - as_float_array(rotor_angle0)))  # [paper], eq. 14
    return wrap_like(panel, series_template(rotor_angle), "panel_angle")


def rotor_speed_from_panel_speed(panel_angle, panel_speed, pinion_radius, lever_arm):
    """Rotor speed of the secondary stepper for a panel speed.

    Parameters
    ----------
    panel_angle : array-like or Series  [rad]
    panel_speed : array-like or Series  [rad/s]
    pinion_radius, lever_arm : float  [m]

    Returns
    -------
    array or Series  [rad/s]
        omega = s omega_p / (r cos^2(panel_angle)).
    """
    radius, arm = _check_transmission(pinion_radius, lever_arm)
    panel = _check_panel_angle(panel_angle, "panel_angle")
    speed = arm * as_float_array(panel_speed) / (radius * np.cos(panel) ** 2)  # [paper], eq. 15
    return wrap_like(speed, series_template(panel_angle, panel_speed), "rotor_speed")
