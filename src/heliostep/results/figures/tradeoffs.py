"""The drive's trade-offs in a run's summary: holding torque against the wind, energy per day.

What a driver offers (microstepping, idle current reduction) costs or saves energy and holding
torque; these figures let a sweep answer "which mode and current for this site".

Details: docs/light.md, ``heliostep.results.figures.tradeoffs``.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping
from typing import Any

import numpy as np

from heliostep.drive.inputs import MOTOR_DEFAULTS, held_current
from heliostep.solar.sun import sun_events

logger = logging.getLogger(__name__)

#: Margin the holding moment must keep over the wind moment: the paper asks for a motor with
#: about twice the computed maximum torque to allow for the wind it leaves out ([paper], before Fig. 11).
REQUIRED_HOLDING_MARGIN = 2.0

#: Holding torque of each energising mode, in units of k_e I ([paper], eq. 9; see the module text).
MODE_HOLDING_FACTOR = {"one-phase-on": 1.0, "two-phase-on": float(np.sqrt(2.0)), "half-step": 1.0}


def holding_torque(current, torque_constant, mode: str = "one-phase-on", fraction=1.0):
    """Holding (pull-out) torque of a two-phase stepper on its shaft.

    Parameters
    ----------
    current : float or array-like  [A]
        Phase current the drive holds (full-current level).
    torque_constant : float  [N.m/A]
        k_e ([paper], Table 3: 0.5 N.m/A).
    mode : {'one-phase-on', 'two-phase-on', 'half-step'}
        Microstepping is one-phase-on's sine/cosine currents: the same factor.
    fraction : float or array-like, default 1  [-]
        Idle current fraction f.

    Returns
    -------
    float or array  [N.m]
        factor(mode) * f * k_e * I ([paper], eq. 9).
    """
    return MODE_HOLDING_FACTOR[mode] * np.asarray(fraction) * torque_constant * np.asarray(current)  # [paper], eq. 9


def drive_ratio(panel_angle, pinion_radius, lever_arm):
    """Rotor angle per panel angle, g = s / (r cos^2 theta_p).

    Parameters
    ----------
    panel_angle : float or array-like  [rad]
    pinion_radius : float  [m]
    lever_arm : float  [m]

    Returns
    -------
    float or array  [-]
        g ([paper], eq. 15); a motor torque C gives the panel the moment g C.
    """
    return lever_arm / (pinion_radius * np.cos(np.asarray(panel_angle)) ** 2)  # [paper], eq. 15


def _motor_constants(scenario) -> dict:
    motor = scenario.roles.instance_of("torque") or "motor"
    return {**MOTOR_DEFAULTS, **scenario.parameters.get(motor, {})}


def smallest_drive_ratio(panel_angle, scenario) -> float:
    """The smallest :func:`drive_ratio` over panel angles [rad] with the scenario's transmission
    (the smallest over a trace is the smallest of its blocks' smallest)."""
    transmission = scenario.transmission
    return float(
        np.min(drive_ratio(np.asarray(panel_angle, dtype=float), transmission.pinion_radius, transmission.lever_arm))
    )


def holding_figures_at(ratio: float, metadata: Mapping, scenario) -> dict:
    """Holding torque at full and idle current against the wind moment, with the window's smallest drive ratio.

    Parameters
    ----------
    ratio : float  [-]
        The smallest drive ratio over the window (:func:`smallest_drive_ratio`).
    metadata : Mapping
        With ``drive`` (mode, current, idle_current_fraction).
    scenario : heliostep.scenario.Scenario

    Returns
    -------
    dict
        ``holding_torque_full_Nm`` and ``holding_torque_idle_Nm`` (motor shaft) [N.m], ``idle_holding_moment_Nm``
        (panel axis, the smallest over the window) [N.m], ``wind_moment_Nm`` [N.m] (with a wind speed: the
        moment at the worst instant, where the holding moment over the wind's is smallest,
        ``metadata['drive']['wind']``; the holding moment is then the one at that instant),
        ``idle_holding_margin`` (holding moment / |wind moment|; None without wind), ``idle_holds_wind``
        (margin >= :data:`REQUIRED_HOLDING_MARGIN`, None without wind), ``warnings`` (when the margin is short).
    """
    drive = metadata["drive"]
    constants = _motor_constants(scenario)
    current = held_current(scenario, float(drive["current"]))
    fraction = float(drive.get("idle_current_fraction", 1.0))
    full = float(holding_torque(current, constants["k_e"], drive["mode"]))
    idle = float(holding_torque(current, constants["k_e"], drive["mode"], fraction))
    moment = ratio * idle
    wind = float(scenario.wind.moment)
    worst = drive.get("wind")
    if worst is not None:  # the wind over time: its worst instant (heliostep.drive.wind_load)
        wind = float(worst["moment_Nm"])
        if worst["drive_ratio"] is not None:
            moment = float(worst["drive_ratio"]) * idle
    figures: dict[str, Any] = {
        "holding_torque_full_Nm": full,
        "holding_torque_idle_Nm": idle,
        "idle_holding_moment_Nm": moment,
        "wind_moment_Nm": wind,
        "idle_holding_margin": None,
        "idle_holds_wind": None,
    }
    if wind == 0.0:
        return figures
    margin = figures["idle_holding_margin"] = moment / abs(wind)
    figures["idle_holds_wind"] = bool(margin >= REQUIRED_HOLDING_MARGIN)
    if margin < REQUIRED_HOLDING_MARGIN:
        consequence = (
            "the rotor slips when the current drops"
            if margin < 1.0
            else f"less than the {REQUIRED_HOLDING_MARGIN:g}x margin the paper asks for wind"
        )
        text = (
            f"holding moment at idle current ({fraction:g} x {current:.3g} A) is {moment:.4g} N.m on the panel "
            f"axis against a wind moment of {abs(wind):.4g} N.m (margin {margin:.3g}): {consequence}; "
            f"raise sequencer.idle_current_fraction or the current"
        )
        figures["warnings"] = [text]
        logger.warning("%s: %s", scenario.name, text)
    return figures


def daylight_seconds(date, site) -> float | None:
    """Sunrise to sunset of a local date at a site [s] (NREL SPA); None on a polar day or night."""
    events = sun_events(date, site)
    if events["sunrise"] is None or events["sunset"] is None:
        return None
    return float((events["sunset"] - events["sunrise"]).total_seconds())


def energy_per_day(summary: Mapping, scenario) -> dict:
    """The drive's electrical energy per day and mean power.

    Parameters
    ----------
    summary : Mapping
        With ``electrical_energy_J`` and ``duration_s``.
    scenario : heliostep.scenario.Scenario

    Returns
    -------
    dict
        ``drive_power_mean_W`` [W] = energy / duration and ``drive_energy_per_day_J`` [J] = that
        times the daylight of the window's date; ``night_power_W`` [W] (:func:`night_power`) and
        ``drive_energy_24h_J`` [J], the day's energy plus the night's at that power; None when not known.
    """
    energy, duration = summary.get("electrical_energy_J"), summary.get("duration_s")
    night = night_power(scenario)
    unknown = {"drive_power_mean_W": None, "drive_energy_per_day_J": None, "drive_energy_24h_J": None}
    if energy is None or not duration:
        return {**unknown, "night_power_W": night}
    power = float(energy) / float(duration)
    daylight = daylight_seconds(scenario.window.date, scenario.site.to_site())
    if daylight is None:
        return {**unknown, "drive_power_mean_W": power, "night_power_W": night}
    return {
        "drive_power_mean_W": power,
        "drive_energy_per_day_J": power * daylight,
        "night_power_W": night,
        "drive_energy_24h_J": power * daylight + night * (SECONDS_PER_DAY - daylight),
    }


#: Phases carrying the current at rest, by sequencer mode: two for two-phase-on, two at half-step's
#: two-phase positions (the larger), one otherwise (sine/cosine microsteps: i_a^2 + i_b^2 = I^2).
PHASES_AT_REST = {"one-phase-on": 1, "two-phase-on": 2, "half-step": 2}
SECONDS_PER_DAY = 86400.0


def night_power(scenario) -> float:
    """The drive's electrical power at night [W] by ``sequencer.night``: the windings' R i^2 at rest, the
    held current i = K I / (K + R) (:func:`heliostep.drive.inputs.held_current`) on the phases the mode keeps
    on (:data:`PHASES_AT_REST`); ``idle``: at ``idle_current_fraction`` of it; ``off``: 0 (a self-locking drive,
    e.g. a worm gear, holds the panel without current)."""
    sequencer = scenario.sequencer
    if sequencer.night == "off":
        return 0.0
    fraction = sequencer.idle_current_fraction if sequencer.night == "idle" else 1.0
    current = held_current(scenario, fraction * sequencer.current)
    resistance = float(_motor_constants(scenario)["R"])
    return PHASES_AT_REST.get(sequencer.mode, 1) * resistance * current**2  # R i^2 per phase on


def tradeoff_figures_at(ratio: float, metadata: Mapping, scenario, summary: Mapping) -> dict:
    """:func:`holding_figures_at` and :func:`energy_per_day` of a run, the window's smallest drive ratio
    ``ratio`` known (its ``warnings`` appended to the summary's own)."""
    figures = {**holding_figures_at(ratio, metadata, scenario), **energy_per_day(summary, scenario)}
    if "warnings" in figures:
        figures["warnings"] = list(summary.get("warnings", [])) + figures["warnings"]
    return figures
