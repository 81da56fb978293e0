"""The load a drive must carry and the torque its motor has against it: the sizing's two sides.

Details: docs/sizing.md, ``heliostep.run.load_budget``.
"""

from __future__ import annotations

import functools
import math
import types
from collections.abc import Mapping
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from heliostep.cosim import read_fmu
from heliostep.drive.inputs import DriveInputs
from heliostep.drive.wind import air_density, panel_wind_moment
from heliostep.scenario import Scenario
from heliostep.scenario.catalogue import MotorDrive

__all__ = [
    "LoadBudget",
    "StowLoad",
    "load_budget",
    "mechanics_values",
    "static_step_limit",
    "step_limit_of_holding",
    "stow_load",
    "wind_moment_at",
]


@dataclass(frozen=True)
class LoadBudget:
    """The load on the motor shaft at the window's worst instant [N.m], and where it is."""

    wind_Nm: float
    friction_Nm: float
    inertia_Nm: float
    total_Nm: float
    time_s: float  # the worst instant, from the window's start
    panel_angle_deg: float
    ratio: float  # g = d theta / d theta_p there
    wind_moment_Nm: float  # on the panel axis
    max_step_rate_per_s: float  # the reference's fastest rotor speed, in full steps per second

    def record(self) -> dict:
        return asdict(self)


def load_budget(
    scenario: Scenario,
    inputs: DriveInputs,
    wind_moment: float | np.ndarray,
    mechanics: Mapping[str, float],
    rotor_inertia: float,
) -> LoadBudget:
    """The load budget over ``inputs``' reference.

    Parameters
    ----------
    wind_moment : float or array
        The design moment on the panel axis [N.m], or the moment at each of ``inputs.reference_times``
        (the wind over time, :func:`wind_moment_at`).
    mechanics : mapping
        The mechanics FMU's ``T_c`` [N.m], ``M_c`` [N.m] and ``J_p`` [kg.m2] (its defaults with the
        scenario's values over them).
    rotor_inertia : float
        J_m [kg.m2], the candidate's.
    """
    transmission = scenario.transmission
    times, panel = inputs.reference_times, inputs.panel_angle_ref
    ratio = transmission.lever_arm / (transmission.pinion_radius * np.cos(panel) ** 2)
    rotor = inputs.rotor_reference()
    acceleration = np.abs(rotor.derivative(2)(times))
    speed = np.abs(rotor.derivative(1)(times))
    wind = abs(wind_moment) / ratio
    friction = mechanics["T_c"] + mechanics["M_c"] / ratio
    inertia = (rotor_inertia + mechanics["J_p"] / ratio**2) * acceleration
    total = wind + friction + inertia
    worst = int(np.argmax(total))
    return LoadBudget(
        wind_Nm=float(wind[worst]),
        friction_Nm=float(friction[worst]),
        inertia_Nm=float(inertia[worst]),
        total_Nm=float(total[worst]),
        time_s=float(times[worst]),
        panel_angle_deg=float(np.degrees(panel[worst])),
        ratio=float(ratio[worst]),
        wind_moment_Nm=float(np.broadcast_to(wind_moment, np.shape(times))[worst]),
        max_step_rate_per_s=float(np.max(speed) / inputs.sequencer.step_angle),
    )


def mechanics_values(scenario: Scenario, instance: str, mechanics_fmu: Path | None) -> dict[str, float]:
    """The mechanics FMU's ``T_c``, ``M_c`` [N.m], ``J_p``, ``J_m`` [kg.m2]: the scenario's
    ``parameters.<instance>`` values over the FMU's defaults (0 where neither has one)."""
    given = scenario.parameters.get(instance, {})
    starts = start_values(mechanics_fmu) if mechanics_fmu is not None else {}
    values = {}
    for name in ("T_c", "M_c", "J_p", "J_m"):
        start = starts.get(name)
        values[name] = float(given[name]) if name in given else (float(start) if isinstance(start, float) else 0.0)
    return values


def start_values(fmu: Path) -> Mapping[str, object]:
    """Each variable's start value in the FMU file ``fmu`` (None without one), read once per version of
    the file (its path, size and modification time): a sweep's cases read the same FMU thousands of times."""
    status = Path(fmu).stat()
    return _start_values(str(Path(fmu).resolve()), status.st_size, status.st_mtime_ns)


@functools.lru_cache(maxsize=32)
def _start_values(path: str, size: int, modified: int) -> Mapping[str, object]:
    variables = read_fmu(path).variables
    return types.MappingProxyType({name: variable.start for name, variable in variables.items()})


def wind_moment_at(inputs: DriveInputs) -> np.ndarray:
    """The wind's moment on the panel axis [N.m] at each reference instant: the ``m_ext`` signal held
    there (``values[0]`` before ``times[0]``, ``values[k + 1]`` from ``times[k]`` on; its sign turned back,
    m_ext = -M), or the constant ``wind_moment`` without a wind speed."""
    signal, times = inputs.wind_signal, inputs.reference_times
    if signal is None:
        return np.full(np.shape(times), float(inputs.wind_moment))
    return -np.asarray(signal.values)[np.searchsorted(signal.times, times, side="right")]


def _transition_limit(a_from: float, a_to: float, delta: float) -> float:
    """The largest static load T with a_to sin(delta + asin(T / a_from)) >= T (bisection) [N.m]."""
    low, high = 0.0, min(a_from, a_to)
    for _ in range(60):
        load = 0.5 * (low + high)
        if a_to * math.sin(delta + math.asin(load / a_from)) >= load:
            low = load
        else:
            high = load
    return low


def static_step_limit(drive: MotorDrive, current: float, mode: str = "one-phase-on", microsteps: int = 1) -> float:
    """The largest static load on the shaft [N.m] against which a step is taken from rest (module docstring)."""
    return step_limit_of_holding(drive.holding_torque(current), mode, microsteps)


def step_limit_of_holding(held: float, mode: str = "one-phase-on", microsteps: int = 1) -> float:
    """:func:`static_step_limit` of a motor whose one-phase holding torque is ``held`` [N.m]."""
    if microsteps > 1:
        return _transition_limit(held, held, math.pi / (2 * microsteps))
    if mode == "two-phase-on":
        return _transition_limit(math.sqrt(2.0) * held, math.sqrt(2.0) * held, math.pi / 2)
    if mode == "half-step":
        one, two = held, math.sqrt(2.0) * held
        return min(_transition_limit(one, two, math.pi / 4), _transition_limit(two, one, math.pi / 4))
    return _transition_limit(held, held, math.pi / 2)


@dataclass(frozen=True)
class StowLoad:
    """The load on the motor shaft during a stow or return move, at each panel angle it travels.

    Attributes (arrays, one value per angle)
    ----------------------------------------
    panel_angles : [rad]
    ratio : g = s / (r cos^2 theta_p) [-]
    step_rate_per_s : the rotor's step rate at the slew rate, g omega_slew / step angle [full steps/s]
    wind_moment_Nm : the wind's moment on the panel axis at the stow speed [N.m]
    wind_Nm, friction_Nm, inertia_Nm, total_Nm : on the shaft [N.m]
    """

    panel_angles: np.ndarray
    ratio: np.ndarray
    step_rate_per_s: np.ndarray
    wind_moment_Nm: np.ndarray
    wind_Nm: np.ndarray
    friction_Nm: np.ndarray
    inertia_Nm: np.ndarray
    total_Nm: np.ndarray


def stow_load(
    scenario: Scenario, panel_angles, mechanics: Mapping[str, float], rotor_inertia: float, step_angle: float
) -> StowLoad | None:
    """The load of a stow move at each of ``panel_angles`` [rad] (None when the scenario never stows).

    The move runs at ``wind.slew_rate`` (omega_p) while the wind blows at the stow threshold
    ``wind.stow_speed`` (the mean speed at which the move starts; with ``wind.gust_factor`` on it, normal
    to the axis: the worst direction), so on the shaft:

    * wind: |C_M(theta_p)| 1/2 rho (G v_stow)^2 A c / g (:func:`heliostep.drive.wind.panel_wind_moment`);
    * friction: T_c + M_c / g;
    * inertia: (J_m + J_p / g^2) alpha, alpha = f^2 phi + 2 g tan(theta_p) omega_p^2: the move starts at
      the slew rate, so the rotor reaches its step rate f = g omega_p / phi within the first step period
      (omega f, omega = f phi), plus the change of g along the move at constant panel speed.

    Parameters
    ----------
    rotor_inertia : float  [kg.m2]
    step_angle : float  [rad], the motor's full step phi.
    """
    wind = scenario.wind
    if wind.stow_speed is None:
        return None
    angles = np.asarray(panel_angles, dtype=float)
    transmission, optics = scenario.transmission, scenario.optics
    ratio = transmission.lever_arm / (transmission.pinion_radius * np.cos(angles) ** 2)
    slew = math.radians(wind.slew_rate)
    rate = ratio * slew / step_angle
    density = air_density(scenario.site.altitude, wind.air_temperature)
    moment = np.abs(
        panel_wind_moment(wind.stow_speed, angles, optics.aperture_area, optics.mirror_width, density, wind.gust_factor)
    )
    acceleration = rate**2 * step_angle + 2.0 * ratio * np.abs(np.tan(angles)) * slew**2
    wind_shaft = moment / ratio
    friction = mechanics["T_c"] + mechanics["M_c"] / ratio
    inertia = (rotor_inertia + mechanics["J_p"] / ratio**2) * acceleration
    return StowLoad(angles, ratio, rate, moment, wind_shaft, friction, inertia, wind_shaft + friction + inertia)
