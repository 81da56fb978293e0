"""The typed sections of a scenario (site, window, plant, mirror, transmission, sequencer, wind, solver, output)."""

from __future__ import annotations

import datetime as dt
import math
import re
from typing import Annotated, Any, Literal

from pydantic import (
    BaseModel,
    BeforeValidator,
    ConfigDict,
    Field,
    field_validator,
    model_validator,
)

from heliostep.cosim.signals import SolverOptions
from heliostep.scenario.keys import KeyProblems
from heliostep.solar import (
    AXES,
    DEFAULT_MIRROR_SPACING,
    N_FIELD_MIRRORS,
    ORIENTATIONS,
    PAPER_LEVER_ARM,
    PAPER_PINION_RADIUS,
    STOW_POLICIES,
    Plant,
    Site,
    check_timezone,
    field_distances,
)
from heliostep.solar.field import PANEL_LENGTH, PANEL_WIDTH
from heliostep.solar.intercept import SURFACE_SLOPE_ERROR
from heliostep.solar.sun import ALTITUDE_RANGE

#: Energising sequences of the stepper sequencer (the drive implements one phase pattern for each).
SEQUENCER_MODES = ("one-phase-on", "two-phase-on", "half-step")
#: When a step is commanded: the reference crosses the midpoint to the next position, or reaches it.
SEQUENCER_TRIGGERS = ("midpoint", "reach")
#: Largest phase current a scenario or a motor catalogue may ask for [A]: hybrid steppers' rated phase
#: currents stay under about 10 A up to NEMA 42 frames, and the chopper drivers for them deliver at most
#: some 20 A; ten times the largest motor's rating leaves room for any real drive and refuses a typo.
MAX_PHASE_CURRENT = 100.0

_CLOCK_TIME = re.compile(r"(\d{1,2}):(\d{2})(?::(\d{2}))?")
SUNRISE, SUNSET = "sunrise", "sunset"


def _parse_clock_time(value: Any, word: str) -> dt.time | str:
    """A local clock time from "HH:MM", "HH:MM:SS", a :class:`datetime.time` or ``word``."""
    if isinstance(value, str) and value.strip().lower() == word:
        return word
    if isinstance(value, dt.time) and value.tzinfo is None:
        return value
    expected = f'a local time "HH:MM" or "HH:MM:SS" (quoted), or {word!r}'
    if not isinstance(value, str):
        raise ValueError(f"expected {expected}, got {value!r}")
    match = _CLOCK_TIME.fullmatch(value.strip())
    if match is None:
        raise ValueError(f"expected {expected}, got {value!r}")
    hour, minute, second = (int(group or 0) for group in match.groups())
    if hour > 23 or minute > 59 or second > 59:
        raise ValueError(f"{value!r} is not a clock time (hours 0-23, minutes and seconds 0-59)")
    return dt.time(hour, minute, second)


def _start_time(value):
    return _parse_clock_time(value, SUNRISE)


def _end_time(value):
    return None if value is None else _parse_clock_time(value, SUNSET)


def _upper(value):
    return value.upper() if isinstance(value, str) else value


#: A real number given as a YAML number (a bool or a quoted string is an error), finite.
Real = Annotated[float, Field(strict=True)]
Count = Annotated[int, Field(strict=True)]


class Section(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)


# --------------------------------------------------------------------------- sections
class SiteConfig(Section):
    """``site``: where the plant is (see :class:`heliostep.solar.Site`)."""

    latitude: Real = Field(ge=-90.0, le=90.0, description="[deg], positive North")
    longitude: Real = Field(ge=-180.0, le=180.0, description="[deg], positive East")
    altitude: Real = Field(
        0.0, ge=ALTITUDE_RANGE[0], le=ALTITUDE_RANGE[1], description="[m] above sea level (land on Earth)"
    )
    timezone: str = Field(description="IANA name such as 'Europe/Rome'")

    @field_validator("timezone")
    @classmethod
    def _known_timezone(cls, value: str) -> str:
        return check_timezone(value)

    def to_site(self) -> Site:
        """The :class:`heliostep.solar.Site` of this section."""
        return Site(latitude=self.latitude, longitude=self.longitude, altitude=self.altitude, timezone=self.timezone)


class WindowConfig(Section):
    """``window``: the simulated time span, in local time of the site.

    ``start`` is "HH:MM[:SS]" or "sunrise"; the span ends after ``duration`` [s] or
    at ``end`` ("HH:MM[:SS]" or "sunset"): exactly one of the two.
    """

    date: dt.date = Field(description="local calendar date, YYYY-MM-DD")
    start: Annotated[dt.time | Literal["sunrise"], BeforeValidator(_start_time)] = Field(
        description='local time "HH:MM" or "HH:MM:SS", or "sunrise"'
    )
    end: Annotated[dt.time | Literal["sunset"] | None, BeforeValidator(_end_time)] = Field(
        None, description='local time "HH:MM" or "HH:MM:SS", or "sunset"; instead of duration'
    )
    duration: Real | None = Field(None, gt=0.0, description="[s]; instead of end")

    @model_validator(mode="after")
    def _one_way_to_end(self) -> WindowConfig:
        if (self.end is None) == (self.duration is None):
            given = "both" if self.end is not None else "neither"
            raise KeyProblems([((), f"give exactly one of 'end' or 'duration' ({given} given)")])
        if isinstance(self.start, dt.time) and isinstance(self.end, dt.time) and self.end <= self.start:
            raise KeyProblems([(("end",), f"must be after start ({self.start}) on the same date, got {self.end}")])
        return self


class PlantConfig(Section):
    """``plant``: the receiver line (see :class:`heliostep.solar.Plant`)."""

    orientation: Annotated[Literal[tuple(ORIENTATIONS)], BeforeValidator(_upper)] = Field(
        "NS", description="tube direction"
    )
    azimuth_offset: Real = Field(0.0, description="[deg], from North toward East")
    tube_height: Real = Field(gt=0.0, description="[m] above the mirror plane")

    def to_plant(self) -> Plant:
        """The :class:`heliostep.solar.Plant` of this section."""
        return Plant(tube_height=self.tube_height, orientation=self.orientation, azimuth_offset=self.azimuth_offset)


class MirrorConfig(Section):
    """``mirror``: which end mirror is driven and how it tracks.

    Its position is ``distance`` [m] from the tube, or ``index`` (0 .. 12, 6 is the
    central mirror) in the field of N_FIELD_MIRRORS mirrors ``spacing`` [m] apart: exactly one of
    ``distance`` and ``index``.
    """

    distance: Real | None = Field(None, description="[m], transverse position; instead of index")
    index: Count | None = Field(
        None,
        ge=0,
        le=N_FIELD_MIRRORS - 1,
        description=f"position in the field of {N_FIELD_MIRRORS}; instead of distance",
    )
    spacing: Real | None = Field(
        None, gt=0.0, description=f"[m] between mirrors, with index (default {DEFAULT_MIRROR_SPACING})"
    )
    axis: Literal[AXES] = Field("secondary", description="the driven axis")
    stow: Literal[STOW_POLICIES] = Field("hold", description="policy while the sun is down")
    stow_angle: Real = Field(0.0, ge=-90.0, le=90.0, description="[deg]")

    @model_validator(mode="after")
    def _one_position(self) -> MirrorConfig:
        if (self.distance is None) == (self.index is None):
            given = "both" if self.index is not None else "neither"
            raise KeyProblems([((), f"give exactly one of 'distance' or 'index' ({given} given)")])
        if self.spacing is not None and self.index is None:
            raise KeyProblems(
                [(("spacing",), "only applies with 'index'; remove it or give 'index' instead of 'distance'")]
            )
        return self

    @property
    def mirror_distance(self) -> float:
        """Transverse position of the mirror [m]: ``distance`` or the index's place in the field."""
        if self.distance is not None:
            return self.distance
        spacing = DEFAULT_MIRROR_SPACING if self.spacing is None else self.spacing
        return float(field_distances(N_FIELD_MIRRORS, spacing)[self.index])


class TransmissionConfig(Section):
    """``transmission``: rack and pinion between rotor and panel (defaults: the paper's Table 2)."""

    pinion_radius: Real = Field(PAPER_PINION_RADIUS, gt=0.0, description="[m]")
    lever_arm: Real = Field(PAPER_LEVER_ARM, gt=0.0, description="[m]")


class SequencerConfig(Section):
    """``sequencer``: how the stepper's phases are energised."""

    mode: Literal[SEQUENCER_MODES] = Field("one-phase-on", description="energising sequence")
    current: Real = Field(5.5, gt=0.0, le=MAX_PHASE_CURRENT, description="[A], phase current")
    step_angle: Real = Field(1.8, gt=0.0, description="[deg], full step of the rotor")
    trigger: Literal[SEQUENCER_TRIGGERS] = Field(
        "midpoint", description="step when the reference crosses the midpoint to the next position, or reaches it"
    )
    microsteps: Literal[1, 2, 4, 8, 16] = Field(
        1, description="sine/cosine phase currents in 1/N of a full step (one-phase-on only); 1: full steps"
    )
    idle_current_fraction: Real = Field(
        1.0, gt=0.0, le=1.0, description="[-], current held after idle_delay without a step; 1: no reduction"
    )
    idle_delay: Real = Field(0.0, ge=0.0, description="[s] after each step before the idle current reduction")
    night: Literal["hold", "idle", "off"] = Field(
        "idle",
        description="the drive from sunset to sunrise: hold at the current, idle at idle_current_fraction of it, "
        "or off (a self-locking drive)",
    )

    @field_validator("night", mode="before")
    @classmethod
    def _yaml_off(cls, value):
        """YAML 1.1 reads an unquoted ``off`` as false: that is the ``off`` policy."""
        return "off" if value is False else value


class SecondaryConfig(Section):
    """``optics.secondary``: a secondary concentrator above the tube (see :mod:`heliostep.solar.intercept`).

    Its aperture, ``aperture_width`` [m] wide, lies in the horizontal plane tangent to the absorber from
    below; it accepts rays within ``acceptance_half_angle`` [deg] of the vertical in the cross-section
    and reflects those that miss the absorber once, with ``reflectivity`` [-].
    """

    aperture_width: Real = Field(gt=0.0, description="[m], width of the aperture across the tube")
    acceptance_half_angle: Real = Field(
        gt=0.0, lt=90.0, description="[deg], acceptance half-angle from the vertical, in the cross-section"
    )
    reflectivity: Real = Field(gt=0.0, le=1.0, description="[-], of the secondary's mirror")

    def receiver(self) -> dict:
        """The mapping :func:`heliostep.solar.intercept.intercept` takes (the angle in radians)."""
        return {
            "aperture_width": self.aperture_width,
            "acceptance_half_angle": math.radians(self.acceptance_half_angle),
            "reflectivity": self.reflectivity,
        }


class OpticsConfig(Section):
    """``optics``: the mirror's light path to the tube (see :mod:`heliostep.solar.intercept`).

    Defaults: the paper's Table 2 panel, 1.5 m long and M / (rho l sp) = 0.3 m wide (the width the
    mechanics' panel uses, :data:`heliostep.solar.field.PANEL_WIDTH`), flat, its aperture width x
    length; the optical chain of seed 004 (rho = 0.80, tau = 0.85, alpha = 0.95); a bare 70 mm
    absorber (no secondary); a surface slope error of 1.53 mrad per axis (SolarPILOT's default for
    silvered glass, :data:`heliostep.solar.intercept.SURFACE_SLOPE_ERROR`), no specularity error;
    clear-sky DNI; a tube longer than the mirror both ways (no end effect; ``tube_ends`` places its
    ends).
    """

    mirror_width: Real = Field(PANEL_WIDTH, gt=0.0, description="[m], across the mirror's secondary axis")
    mirror_length: Real = Field(PANEL_LENGTH, gt=0.0, description="[m], along the tube (the panel's long axis)")
    mirror_area: Real | None = Field(
        None, gt=0.0, description="[m^2], reflecting aperture; null: mirror_width x mirror_length"
    )
    focal_length: Real | None = Field(
        None, gt=0.0, description="[m], curvature about the long axis (near the slant distance); null: flat"
    )
    reflectivity: Real = Field(0.80, ge=0.0, le=1.0, description="[-], rho of the mirror")
    transmittance: Real = Field(0.85, ge=0.0, le=1.0, description="[-], tau of the tube's glass")
    absorptance: Real = Field(0.95, ge=0.0, le=1.0, description="[-], alpha of the tube")
    tube_diameter: Real = Field(0.07, gt=0.0, description="[m], the absorber (inside its glass envelope)")
    secondary: SecondaryConfig | None = Field(None, description="a secondary concentrator; null: a bare tube")
    slope_error: Real = Field(
        SURFACE_SLOPE_ERROR, ge=0.0, description="[rad], RMS surface slope error per axis of the mirror"
    )
    specularity: Real = Field(0.0, ge=0.0, description="[rad], specularity error")
    weather_file: str | None = Field(None, description="TMY3 (.csv) or EPW (.epw) file; null: clear sky")
    tube_ends: tuple[Real, Real] | None = Field(
        None,
        description="[m], y of the tube's two ends from the mirror's centre, along the tube (+y: North "
        "for a NS plant); null: the tube runs on past the mirror both ways",
    )

    @model_validator(mode="after")
    def _tube_ends_in_order(self) -> OpticsConfig:
        if self.tube_ends is not None and not self.tube_ends[0] < self.tube_ends[1]:
            raise KeyProblems(
                [(("tube_ends",), f"expected [start, end] with start < end [m], got {list(self.tube_ends)}")]
            )
        return self

    @property
    def aperture_area(self) -> float:
        """The mirror's reflecting area [m^2]: ``mirror_area``, or width x length."""
        return self.mirror_width * self.mirror_length if self.mirror_area is None else self.mirror_area

    def receiver(self) -> dict:
        """The receiver as :func:`heliostep.solar.intercept.intercept` takes it."""
        return {
            "tube_diameter": self.tube_diameter,
            "secondary": None if self.secondary is None else self.secondary.receiver(),
        }

    def mirror(self) -> dict:
        """The mirror's surface as :func:`heliostep.solar.intercept.intercept` takes it."""
        return {
            "width": self.mirror_width,
            "length": self.mirror_length,
            "focal_length": self.focal_length,
            "slope_error": self.slope_error,
            "specularity": self.specularity,
        }


#: Stow above this mean wind speed [m/s]: a heliostat meets its operating requirements up to 12 m/s
#: (typical requirements, after Stine & Geyer, *Power From The Sun*, 2001, ch. 10; docs/physics.md).
DEFAULT_STOW_SPEED = 12.0
#: The panel's slew rate while stowing and returning [deg/s] (stated, not sourced: 90 deg in 3 min).
DEFAULT_SLEW_RATE = 0.5
#: Calm time before returning to tracking [s]: WMO's 10-min averaging period of the mean wind
#: (WMO-No. 8, *Guide to Instruments and Methods of Observation*, ch. 5).
DEFAULT_CALM_TIME = 600.0
#: Peak over mean speed applied to the moment (Durst 1960; heliostep.drive.wind.DURST_GUST_FACTOR).
DEFAULT_GUST_FACTOR = 1.52


class WindConfig(Section):
    """``wind``: external load on the panel, and stow in high wind.

    The load is a constant ``moment`` [N.m], or the moment of a wind speed
    (:func:`heliostep.drive.wind.panel_wind_moment`) from one source: a constant ``speed``, a
    ``weather_file`` (TMY3/EPW, its wind speed at its stamps) or a ``profile`` (a design gust,
    [time from the window start [s], speed [m/s]] points, linear between them); its component normal
    to the panel's axis loads the panel, the wind from ``direction`` (null: the file's, else the worst
    case, normal to the axis). With a speed the
    panel stows above ``stow_speed`` (null: never) at ``slew_rate`` to ``stow_angle`` and returns
    once the wind has stayed at or below it for ``calm_time``.
    """

    moment: Real = Field(0.0, description="[N.m], constant moment on the panel (no wind speed)")
    speed: Real | None = Field(None, ge=0.0, description="[m/s], constant mean wind speed")
    weather_file: str | None = Field(None, description="TMY3 (.csv) or EPW (.epw) file whose wind speed is used")
    profile: list[tuple[Real, Real]] | None = Field(
        None, description="design gust: [[time [s] from the window start, speed [m/s]], ...], linear between"
    )
    direction: Real | None = Field(
        None,
        ge=0.0,
        le=360.0,
        description="[deg] the wind blows from, clockwise from north; null: the weather file's where it has one, "
        "else normal to the panel's axis (the worst case)",
    )
    gust_factor: Real = Field(DEFAULT_GUST_FACTOR, ge=1.0, description="[-], peak over mean speed, on the moment")
    air_temperature: Real | None = Field(
        None, gt=-90.0, lt=60.0, description="[degC]; null: the ISA's at the site's altitude"
    )
    stow_speed: Real | None = Field(
        DEFAULT_STOW_SPEED, ge=0.0, description="[m/s], stow above this mean wind speed; null: never stow"
    )
    stow_angle: Real = Field(0.0, ge=-90.0, le=90.0, description="[deg], panel angle held while stowed")
    slew_rate: Real = Field(DEFAULT_SLEW_RATE, gt=0.0, description="[deg/s], panel speed of the stow moves")
    calm_time: Real = Field(DEFAULT_CALM_TIME, ge=0.0, description="[s] at or below stow_speed before returning")
    update_interval: Real = Field(
        10.0, gt=0.0, description="[s], longest hold of the moment signal between the drive's steps"
    )

    @model_validator(mode="after")
    def _one_source(self) -> WindConfig:
        given = [key for key in ("speed", "weather_file", "profile") if getattr(self, key) is not None]
        if len(given) > 1:
            raise KeyProblems([((given[1],), f"give one wind speed source, got {', '.join(given)}")])
        if self.direction is not None and not given:
            raise KeyProblems(
                [(("direction",), "a wind direction needs a wind speed (speed, weather_file or profile)")]
            )
        if given and self.moment != 0.0:
            raise KeyProblems([(("moment",), f"a constant moment or a wind speed ({given[0]}), not both")])
        if self.profile is not None:
            times = [point[0] for point in self.profile]
            if len(times) < 2 or any(b <= a for a, b in zip(times, times[1:])):
                raise KeyProblems([(("profile",), "expected at least two points with increasing times [s]")])
            if any(point[1] < 0.0 for point in self.profile):
                raise KeyProblems([(("profile",), "speeds must be >= 0 [m/s]")])
        return self

    @property
    def has_speed(self) -> bool:
        """Whether the load comes from a wind speed (not a constant moment)."""
        return self.speed is not None or self.weather_file is not None or self.profile is not None


class SolverConfig(Section):
    """``solver``: settings of the master's ODE solver."""

    rtol: Real = Field(SolverOptions.rtol, gt=0.0, le=0.1, description="relative tolerance")
    atol: Real | None = Field(None, gt=0.0, description="absolute tolerance, null: the solver's default")
    max_step: Real | None = Field(None, gt=0.0, description="[s], null: no limit")
    max_num_steps: Count = Field(SolverOptions.max_num_steps, gt=0, description="solver steps at most")
    loop_rtol: Real = Field(
        SolverOptions.loop_rtol,
        ge=0.0,
        le=0.1,
        description="relative tolerance of the algebraic loops' Newton: solved when |y(v) - v| <= "
        "loop_atol + loop_rtol |v| for every torn input v",
    )
    loop_atol: Real = Field(
        SolverOptions.loop_atol, gt=0.0, description="absolute tolerance of the algebraic loops' Newton [v's unit]"
    )


class OutputConfig(Section):
    """``output``: time grid of the trace."""

    interval: Real = Field(0.01, gt=0.0, description="[s], spacing of the regular grid")
    step_detail: Real = Field(
        0.05, ge=0.0, description="[s] after each step kept on the fine grid (0: none, the row at the step only)"
    )
    step_interval: Real = Field(0.0005, gt=0.0, description="[s], spacing of the fine grid")


class BudgetConfig(Section):
    """``budget``: the most a run may take, checked against an estimate made from the scenario
    before anything is computed (:mod:`heliostep.run.estimate`); above it the run is refused
    (exit 2) naming the key that makes it large. The defaults fit a laptop."""

    memory_gb: Real = Field(4.0, gt=0.0, description="[GB] of memory the run's inputs and trace may take")
    disk_gb: Real = Field(10.0, gt=0.0, description="[GB] of disk its files (trace, CSV, records) may take")


class BandConfig(Section):
    """``band``: how ``heliostep run --band N`` treats this scenario (:mod:`heliostep.sweep.band`).

    A scenario that states a value as its source's (the paper's ±3.1 V bus in
    ``jan21-paper-literal``) lists that key in ``pinned``: the band leaves it at the scenario's
    value and samples only the others of the ranges file."""

    pinned: list[str] = Field(
        default_factory=list,
        description="keys of the ranges file (e.g. parameters.motor.V_supply) the band keeps at this scenario's value",
    )
