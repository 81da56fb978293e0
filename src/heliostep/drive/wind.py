"""The wind as a load on the panel axis: moment coefficient, air density, gust factor (pure, vectorised).

M = C_M(alpha) 1/2 rho (G v)^2 A c, with a flat plate's moment coefficient about its mid-chord
(Hoerner's normal force, Joessel's centre of pressure), the wind's cross-axis component, the ISA's
air density and Durst's gust factor.

Details: docs/physics.md, ``heliostep.drive.wind``.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "DURST_GUST_FACTOR",
    "ISA_SEA_LEVEL_DENSITY",
    "air_density",
    "attack_angle",
    "centre_of_pressure",
    "cross_wind_moment",
    "cross_wind_speed",
    "external_moment",
    "moment_coefficient",
    "normal_force_coefficient",
    "panel_wind_moment",
]

#: Hoerner's flat plate beyond stall: C_N = 1 / (A + B / sin alpha) (Fluid-Dynamic Drag, 1965).
HOERNER_A, HOERNER_B = 0.222, 0.283
#: Joessel's centre of pressure of a flat plate: x_cp / c = 0.195 + 0.305 sin alpha.
JOESSEL_A, JOESSEL_B = 0.195, 0.305
#: ISO 2533 (ISA) sea-level pressure [Pa], temperature [K], lapse rate [K/m].
ISA_PRESSURE, ISA_TEMPERATURE, ISA_LAPSE_RATE = 101325.0, 288.15, 0.0065
#: Specific gas constant of dry air [J/(kg.K)] and the ISA's exponent g M / (R* L) [-] (ISO 2533).
AIR_GAS_CONSTANT, ISA_EXPONENT = 287.05287, 5.25588
#: ISA sea-level density [kg/m^3] (1.225).
ISA_SEA_LEVEL_DENSITY = ISA_PRESSURE / (AIR_GAS_CONSTANT * ISA_TEMPERATURE)
#: Peak 3-s gust over the hourly mean speed, open terrain, 10 m (Durst 1960; ASCE 7-16 Fig. C26.5-1).
DURST_GUST_FACTOR = 1.52


def _attack(panel_angle) -> np.ndarray:
    """The angle of attack [rad] of a horizontal wind on a panel tilted ``panel_angle`` [rad]: in [0, pi/2]."""
    return np.arcsin(np.clip(np.abs(np.sin(np.asarray(panel_angle, dtype=float))), 0.0, 1.0))


def normal_force_coefficient(attack) -> np.ndarray:
    """Normal force coefficient C_N [-] of a flat plate at angle of attack ``attack`` [rad].

    Hoerner (Fluid-Dynamic Drag, 1965), C_N = 1 / (0.222 + 0.283 / sin alpha); 0 edge-on."""
    s = np.abs(np.sin(np.asarray(attack, dtype=float)))
    with np.errstate(divide="ignore"):
        return np.where(s > 0.0, 1.0 / (HOERNER_A + HOERNER_B / np.where(s > 0.0, s, 1.0)), 0.0)  # [Hoerner], ch. 3


def centre_of_pressure(attack) -> np.ndarray:
    """Centre of pressure from the windward edge, as a fraction of the chord [-], at ``attack`` [rad] in [0, pi/2].

    Joessel's law, x_cp / c = 0.195 + 0.305 sin alpha."""
    alpha = np.clip(np.abs(np.asarray(attack, dtype=float)), 0.0, np.pi / 2)
    return JOESSEL_A + JOESSEL_B * np.sin(alpha)  # [Joessel], x_cp(alpha)


def moment_coefficient(attack) -> np.ndarray:
    """Moment coefficient C_M [-] about the mid-chord at ``attack`` [rad]: C_N (1/2 - x_cp / c), >= 0."""
    alpha = np.clip(np.abs(np.asarray(attack, dtype=float)), 0.0, np.pi / 2)
    return normal_force_coefficient(alpha) * (0.5 - centre_of_pressure(alpha))  # lever of C_N about mid-chord


def air_density(altitude, temperature=None) -> np.ndarray:
    """Air density [kg/m^3] at ``altitude`` [m]: ISA pressure (ISO 2533), at ``temperature`` [degC] or the ISA's.

    Parameters
    ----------
    altitude : float or array  [m]
        Above sea level (the troposphere, below 11 km).
    temperature : float or array, optional  [degC]
        The air's temperature; None: the ISA's, 15 degC - 6.5 K/km x altitude.
    """
    h = np.asarray(altitude, dtype=float)
    pressure = ISA_PRESSURE * (1.0 - ISA_LAPSE_RATE * h / ISA_TEMPERATURE) ** ISA_EXPONENT  # [ISO 2533], troposphere
    kelvin = ISA_TEMPERATURE - ISA_LAPSE_RATE * h if temperature is None else np.asarray(temperature) + 273.15
    return pressure / (AIR_GAS_CONSTANT * kelvin)  # ideal gas


def cross_wind_speed(speed, direction=None, axis_azimuth: float = 0.0) -> np.ndarray:
    """The wind's horizontal component normal to the panel's axis [m/s], signed (the module's docstring).

    Parameters
    ----------
    speed : float or array  [m/s]
        Mean wind speed.
    direction : float or array, optional  [deg]
        Where the wind blows *from*, clockwise from north (meteorological); None or NaN: normal to the
        axis (the worst case, ``speed`` itself).
    axis_azimuth : float  [deg]
        The panel's axis, clockwise from north (an axis is the same at psi and psi + 180 deg).

    Returns
    -------
    numpy.ndarray  [m/s]
        u = -v sin(phi - psi): > 0 blowing towards azimuth psi + 90 deg, where the panel's normal
        tilts at positive angles.
    """
    v = np.asarray(speed, dtype=float)
    if direction is None:
        return v
    phi = np.asarray(direction, dtype=float)
    cross = -v * np.sin(np.radians(phi - axis_azimuth))  # cross-flow principle (Sears 1948)
    return np.where(np.isfinite(phi), cross, v)


def attack_angle(panel_angle, cross_speed) -> np.ndarray:
    """The signed angle of attack [rad]: ``panel_angle`` in the frame of a wind blowing towards the
    panel's positive side, i.e. -``panel_angle`` for a wind ``cross_speed`` < 0 (from that side)."""
    theta = np.asarray(panel_angle, dtype=float)
    return np.where(np.asarray(cross_speed, dtype=float) < 0.0, -theta, theta)


def cross_wind_moment(cross_speed, panel_angle, area: float, chord: float, density, gust_factor: float = 1.0):
    """The moment [N.m] of a wind component ``cross_speed`` [m/s] normal to the axis (signed,
    :func:`cross_wind_speed`) on a panel at ``panel_angle`` [rad], in the sense of positive rotation:
    M = sign(u) C_M*(beta) 1/2 rho (G u)^2 A c, beta = :func:`attack_angle`, C_M* the flat plate's odd curve."""
    u = np.asarray(cross_speed, dtype=float)
    beta = attack_angle(panel_angle, u)
    side = np.where(u < 0.0, -1.0, 1.0)  # the wind's frame back to the panel's
    coefficient = np.sign(np.sin(beta)) * moment_coefficient(_attack(beta))  # C_M*(beta), odd
    dynamic_pressure = 0.5 * np.asarray(density, dtype=float) * (gust_factor * u) ** 2  # q = rho (G u)^2 / 2
    moment = side * coefficient * dynamic_pressure * area * chord  # M = C_M q A c
    return float(moment) if np.ndim(moment) == 0 else moment


def panel_wind_moment(
    speed,
    panel_angle,
    area: float,
    chord: float,
    density=ISA_SEA_LEVEL_DENSITY,
    gust_factor: float = 1.0,
    *,
    direction=None,
    axis_azimuth: float = 0.0,
):
    """The wind's moment on the panel axis [N.m], in the sense of positive rotation (vectorised).

    M = sign(theta_p) C_M(|theta_p|) 1/2 rho (G u)^2 A c, u the wind's component normal to the axis
    (the module's docstring: sources, signs, the direction).

    Parameters
    ----------
    speed : float or array  [m/s]
        Mean wind speed, horizontal.
    panel_angle : float or array  [rad]
        The panel's tilt from horizontal about its axis.
    area : float  [m^2]
        The mirror's area.
    chord : float  [m]
        The mirror's width across its axis.
    density : float or array, default ISA sea level  [kg/m^3]
        :func:`air_density`.
    gust_factor : float, default 1  [-]
        Peak over mean speed (:data:`DURST_GUST_FACTOR` for a mean from a weather file).
    direction : float or array, optional  [deg]
        Where the wind blows from, clockwise from north; None (or NaN): normal to the axis, the worst case.
    axis_azimuth : float, default 0  [deg]
        The panel's axis, clockwise from north.

    Returns
    -------
    float or numpy.ndarray  [N.m]
        Positive where it turns the panel towards positive angles (a float for scalar inputs).
    """
    cross = cross_wind_speed(speed, direction, axis_azimuth)
    return cross_wind_moment(cross, panel_angle, area, chord, density, gust_factor)


def external_moment(speed, panel_angle, area: float, chord: float, density, gust_factor: float = 1.0):
    """The mechanics FMU's ``m_ext`` [N.m] (opposing positive rotation) of a wind component ``speed``
    [m/s] normal to the axis (signed, :func:`cross_wind_speed`): ``-cross_wind_moment(...)``."""
    return -cross_wind_moment(speed, panel_angle, area, chord, density, gust_factor)
