"""The scenario: one run of the co-simulation, validated (unknown keys are errors)."""

from __future__ import annotations

import datetime as dt
import os
import zoneinfo
from collections.abc import Mapping
from pathlib import Path
from typing import Annotated, cast

import pandas as pd
from pydantic import (
    BeforeValidator,
    Field,
    PrivateAttr,
    StrictBool,
    StrictInt,
    StrictStr,
    field_validator,
    model_validator,
)

from heliostep.cosim.signals import SolverOptions
from heliostep.errors import InputError
from heliostep.fmu.reference import is_variant_name
from heliostep.scenario.keys import KeyProblems, dotted
from heliostep.scenario.links import (
    DEFAULT_CONNECTIONS,
    INSTANCE_NAME,
    LinearTransformation,
    connection_pair,
    connection_problems,
    endpoint_problem,
)
from heliostep.scenario.roles import REQUIRED_ROLES, RolesConfig
from heliostep.scenario.sections import (
    SUNRISE,
    SUNSET,
    BandConfig,
    BudgetConfig,
    MirrorConfig,
    OpticsConfig,
    OutputConfig,
    PlantConfig,
    Section,
    SequencerConfig,
    SiteConfig,
    SolverConfig,
    TransmissionConfig,
    WindConfig,
    WindowConfig,
)
from heliostep.scenario.tracking import (
    FaultsConfig,
    TrackingConfig,
    with_sensor,
    with_sensor_connection,
)
from heliostep.solar import sun_events

#: FMU instances of a scenario without ``fmus``: instance name -> variant name.
DEFAULT_FMUS = {"motor": "StepperMotor", "mechanics": "PanelMechanics"}

#: A parameter value of any FMI 2.0 type; the master checks it against the variable's declared type
#: (a Boolean must be true/false, an Integer a whole number, a String quoted text).
ParameterValue = Annotated[
    StrictBool | StrictInt | Annotated[float, Field(strict=True, allow_inf_nan=False)] | StrictStr,
    Field(union_mode="left_to_right"),
]

#: Top-level keys whose null value means "the defaults".
_DEFAULTED_KEYS = (
    "transmission",
    "fmus",
    "parameters",
    "roles",
    "sequencer",
    "wind",
    "solver",
    "output",
    "optics",
    "budget",
    "band",
    "tracking",
    "faults",
)


def _merge_default_fmus(value):
    """Entries of ``fmus`` over :data:`DEFAULT_FMUS`; a null entry drops that instance."""
    if not isinstance(value, Mapping):
        return value
    merged = {**DEFAULT_FMUS, **value}
    return {name: variant for name, variant in merged.items() if variant is not None}


# --------------------------------------------------------------------------- scenario
#: The years a window may be in: pandas' nanosecond timestamps reach 1677-09-21 to 2262-04-11
#: (pvlib's SPA itself is valid from -2000 to 6000).
FIRST_YEAR, LAST_YEAR = 1678, 2261


def _whole_minutes(date: dt.date, zone: zoneinfo.ZoneInfo) -> bool:
    offset = zone.utcoffset(dt.datetime.combine(date, dt.time(12)))
    return offset is None or offset.total_seconds() % 60 == 0


def window_date_problem(date: dt.date, timezone: str) -> str | None:
    """Why the window cannot be on ``date`` at a site in ``timezone`` (None: it can): a year
    outside pandas' timestamps, or a day when the zone kept local mean time (an offset of
    seconds, e.g. Europe/Rome before 1 November 1893), which pandas cannot parse."""
    if not FIRST_YEAR <= date.year <= LAST_YEAR:
        return f"{date}: expected a date in the years {FIRST_YEAR} to {LAST_YEAR} (pandas' timestamps)"
    zone = zoneinfo.ZoneInfo(timezone)
    if _whole_minutes(date, zone):
        return None
    low, high = date.toordinal(), dt.date(LAST_YEAR, 12, 31).toordinal()  # the first whole-minute day after
    while low < high:
        middle = (low + high) // 2
        low, high = (low, middle) if _whole_minutes(dt.date.fromordinal(middle), zone) else (middle + 1, high)
    offset = zone.utcoffset(dt.datetime.combine(date, dt.time(12)))
    return (
        f"{date}: {timezone} then kept local mean time (UTC offset {offset}), which pandas' timestamps "
        f"cannot take; expected a date from {dt.date.fromordinal(low)} on"
    )


class Scenario(Section):
    """A validated scenario: one run of the co-simulation.

    Build it with :func:`load_scenario` (from a file) or :func:`validate_scenario`
    (from a mapping); both raise :class:`~heliostep.errors.InputError` on bad input.
    """

    name: str = Field(min_length=1, description="name of the run")
    description: str | None = None
    site: SiteConfig
    window: WindowConfig
    plant: PlantConfig
    mirror: MirrorConfig
    transmission: TransmissionConfig = Field(default_factory=TransmissionConfig)
    fmus: Annotated[dict[str, str], BeforeValidator(_merge_default_fmus)] = Field(
        default_factory=lambda: dict(DEFAULT_FMUS),
        description="instance name -> model variant or path to an .fmu; merged over the defaults "
        "motor: StepperMotor, mechanics: PanelMechanics (null drops one)",
    )
    system: str | None = Field(None, description="an SSP 1.0 file giving fmus, connections, parameters")
    parameters: dict[str, dict[str, ParameterValue]] = Field(
        default_factory=dict,
        description="instance name -> {parameter name: value (Real, Integer, Boolean or "
        "String, as the FMU declares it)}",
    )
    connections: list[Annotated[tuple[str, str], BeforeValidator(connection_pair)]] | None = Field(
        None, description="[source, target] pairs 'instance.variable'; null: the default connections"
    )
    transformations: dict[str, LinearTransformation] = Field(
        default_factory=dict, description="connection target 'instance.variable' -> {factor, offset} its value takes"
    )
    communication_interval: dict[str, Annotated[float, Field(gt=0, allow_inf_nan=False)]] = Field(
        default_factory=dict, description="instance -> [s]: that FMU runs as Co-Simulation, sampled at this interval"
    )
    roles: RolesConfig = Field(default_factory=RolesConfig)
    sequencer: SequencerConfig = Field(default_factory=SequencerConfig)
    wind: WindConfig = Field(default_factory=WindConfig)
    optics: OpticsConfig = Field(default_factory=OpticsConfig)
    solver: SolverConfig = Field(default_factory=SolverConfig)
    output: OutputConfig = Field(default_factory=OutputConfig)
    budget: BudgetConfig = Field(default_factory=BudgetConfig)
    band: BandConfig = Field(default_factory=BandConfig)
    tracking: TrackingConfig = Field(default_factory=TrackingConfig)
    faults: FaultsConfig = Field(default_factory=FaultsConfig)

    _folder: Path = PrivateAttr(default_factory=Path.cwd)
    _source: str = PrivateAttr(default="<scenario>")

    @model_validator(mode="before")
    @classmethod
    def _empty_means_default(cls, data):
        """An empty (null) section takes its defaults, e.g. ``wind:`` with its lines commented out."""
        if not isinstance(data, Mapping):
            return data
        data = {key: value for key, value in data.items() if not (value is None and key in _DEFAULTED_KEYS)}
        data = with_sensor(data)  # a closed or hybrid loop's sun sensor
        if isinstance(data.get("parameters"), Mapping):
            data["parameters"] = {
                instance: {} if values is None else values for instance, values in data["parameters"].items()
            }
        return data

    @field_validator("name")
    @classmethod
    def _not_blank(cls, value: str) -> str:
        value = value.strip()
        if not value:
            raise ValueError("must not be blank")
        if any(not c.isprintable() for c in value):
            raise ValueError(f"{value!r}: a name is one line of printable text (no line break or control character)")
        if value in (".", "..") or any(c in value for c in "/\\\0") or os.path.isabs(value):
            raise ValueError(
                f"{value!r}: a name is one folder name (the default output folder is out/NAME): "
                "no path separator, not absolute, not '.' or '..'"
            )
        return value

    @field_validator("fmus")
    @classmethod
    def _fmu_names(cls, fmus: dict[str, str]) -> dict[str, str]:
        problems: list[tuple[tuple, str]] = []
        if not fmus:
            problems.append(((), "at least one FMU instance is needed"))
        for instance, variant in fmus.items():
            if not INSTANCE_NAME.fullmatch(instance):
                problems.append(
                    ((instance,), "instance names are identifiers (letters, digits, '_', not starting with a digit)")
                )
            if not variant.strip():
                problems.append(((instance,), "expected a model variant name or a path to an .fmu, got ''"))
        if problems:
            raise KeyProblems(problems)
        return fmus

    @field_validator("connections")
    @classmethod
    def _connection_endpoints(cls, connections):
        if connections is None:
            return None
        problems: list[tuple[tuple, str]] = []
        for position, pair in enumerate(connections):
            for side, endpoint in enumerate(pair):
                problem = endpoint_problem(endpoint)
                if problem:
                    problems.append(((position, side), problem))
            if pair[0] == pair[1]:
                problems.append(((position,), f"connects {pair[0]!r} to itself"))
        if problems:
            raise KeyProblems(problems)
        return connections

    @model_validator(mode="after")
    def _sampled_instances(self) -> Scenario:
        """``communication_interval`` names instances of ``fmus``."""
        unknown = [name for name in self.communication_interval if name not in self.fmus]
        if unknown:
            instances = ", ".join(self.fmus)
            raise KeyProblems(
                [
                    (("communication_interval", name), f"unknown FMU instance; instances in fmus: {instances}")
                    for name in unknown
                ]
            )
        return self

    @model_validator(mode="after")
    def _consistent_sections(self) -> Scenario:
        problems: list[tuple[tuple, str]] = []
        instances = ", ".join(self.fmus)
        for instance in self.parameters:
            if instance not in self.fmus:
                problems.append((("parameters", instance), f"unknown FMU instance; instances in fmus: {instances}"))
        problems += connection_problems(self.connections, self.fmus, self.transformations, instances)
        problems += _role_problems(self)
        date_problem = window_date_problem(self.window.date, self.site.timezone)
        if date_problem:
            problems.append((("window", "date"), date_problem))
        room = (dt.date(LAST_YEAR, 12, 31) - self.window.date).total_seconds()
        if self.window.duration is not None and self.window.duration > room:
            problems.append(
                (
                    ("window", "duration"),
                    f"{self.window.duration:g} s ends after {LAST_YEAR}-12-31; expected <= {room:g}",
                )
            )
        if not problems:  # (a date or duration pandas cannot take is not resolved)
            try:
                _window_bounds(self.window, self.site)
            except KeyProblems as exc:
                problems += exc.problems
        if problems:
            raise KeyProblems(problems)
        return self

    # ----------------------------------------------------------------------- queries
    def connection_pairs(self) -> list[tuple[str, str]]:
        """Effective connections: ``connections``, or :data:`DEFAULT_CONNECTIONS` when omitted.

        Returns
        -------
        list of (str, str)
            (source, target) as "instance.variable".
        """
        pairs = DEFAULT_CONNECTIONS if self.connections is None else self.connections
        pairs = with_sensor_connection(pairs, self.tracking, self.roles.panel_angle)
        return [cast("tuple[str, str]", tuple(pair)) for pair in pairs]

    def transformation(self, target: str) -> tuple[float, float] | None:
        """The (factor, offset) of the connection driving ``target`` ('instance.variable'), None without."""
        given = self.transformations.get(target)
        return None if given is None else (given.factor, given.offset)

    def resolved_roles(self) -> dict[str, str]:
        """Role -> ``instance.variable`` for this scenario's FMUs.

        Roles the scenario sets are kept as given; a default role whose instance is not in
        ``fmus`` is dropped (a required one is an error at validation).
        """
        given = self.roles.model_fields_set
        return {
            role: target
            for role, target in self.roles.present().items()
            if role in given or target.partition(".")[0] in self.fmus
        }

    def fmu_reference(self, instance: str) -> str | Path:
        """What ``fmus[instance]`` refers to.

        Parameters
        ----------
        instance : str
            An FMU instance name, a key of ``fmus``.

        Returns
        -------
        str or pathlib.Path
            The variant name unchanged when it is a bare name (no "/" and not ending
            in ".fmu"), else the path resolved against the scenario file's folder
            (the current directory for a scenario not read from a file).
        """
        if instance not in self.fmus:
            raise InputError(f"{self._source}: fmus: no FMU instance {instance!r}; instances: {', '.join(self.fmus)}")
        reference = self.fmus[instance]
        if is_variant_name(reference):
            return reference
        path = Path(reference).expanduser()
        return path if path.is_absolute() else (self._folder / path).resolve()

    def window_bounds(self) -> tuple[pd.Timestamp, pd.Timestamp]:
        """Start and end of the simulated window.

        "sunrise" and "sunset" are computed with NREL's SPA
        (:func:`heliostep.solar.sun_events`) for the window's date
        and the site.

        Returns
        -------
        start, end : pandas.Timestamp
            Timezone-aware, in the site's timezone.
        """
        try:
            return _window_bounds(self.window, self.site)
        except KeyProblems as exc:
            raise InputError(
                "\n".join(f"{self._source}: {dotted(path)}: {message}" for path, message in exc.problems)
            ) from None

    def resolved_dict(self) -> dict:
        """The fully validated scenario as plain JSON-able data (for run metadata).

        Defaults are filled in, ``fmus`` is merged over :data:`DEFAULT_FMUS` (a default instance
        the scenario dropped stays as null, so it is not merged back) and ``connections`` is the
        effective list; reading it back gives an equal scenario.
        """
        data = self.model_dump(mode="json")
        data["fmus"] = {**{name: None for name in DEFAULT_FMUS if name not in self.fmus}, **data["fmus"]}
        data["roles"] = self.resolved_roles()  # only the roles its FMUs can play (defaults of dropped instances go)
        data["connections"] = [list(pair) for pair in self.connection_pairs()]
        # sections and keys added since resolved scenarios were first written, at their defaults, are left out,
        # so that resolved scenarios (and sweep case ids) stay as they were
        if not self.transformations:
            del data["transformations"]
        if not self.band.pinned:
            del data["band"]
        for key, default in (("tracking", TrackingConfig()), ("faults", FaultsConfig())):
            if getattr(self, key) == default:
                del data[key]
        for key in ("loop_rtol", "loop_atol"):
            if data["solver"][key] == getattr(SolverOptions, key):
                del data["solver"][key]
        return data

    @property
    def source(self) -> str:
        """Where the scenario came from (its file), for error messages."""
        return self._source

    @property
    def folder(self) -> Path:
        """Folder that relative FMU paths are resolved against."""
        return self._folder


def _role_problems(self: Scenario) -> list:
    """The ``roles`` that name no variable of the scenario's FMUs, or none where one is required."""
    problems: list[tuple[tuple, str]] = []
    given = self.roles.model_fields_set
    instances = ", ".join(self.fmus)
    for role, target in self.roles.model_dump().items():
        if target is None:
            if role in REQUIRED_ROLES:
                problems.append((("roles", role), "this role is required: give the 'instance.variable' it is"))
            continue
        problem = endpoint_problem(target)
        instance = target.partition(".")[0]
        if role in given and problem:
            problems.append((("roles", role), problem))
        elif role in given and instance not in self.fmus:
            problems.append(
                (("roles", role), f"{target!r}: unknown FMU instance {instance!r}; instances in fmus: {instances}")
            )
        elif role not in given and instance not in self.fmus and role in REQUIRED_ROLES:
            problems.append(
                (
                    ("roles", role),
                    f"the default {target!r} uses FMU instance {instance!r}, not in "
                    f"fmus ({instances}); give roles.{role} explicitly",
                )
            )
    return problems


def _window_bounds(window: WindowConfig, site: SiteConfig) -> tuple[pd.Timestamp, pd.Timestamp]:
    """Start and end of *window* at *site*, in its timezone (:class:`KeyProblems` naming ``window.*``
    when a clock time does not exist there or the sun does not rise or set)."""
    timezone = site.timezone
    events = None

    def sun_event(column: str, key: str) -> pd.Timestamp:
        nonlocal events
        if events is None:
            events = sun_events(window.date, site.to_site())
        stamp = events[column]
        if stamp is None:
            message = f"the sun has no {column} on {window.date} at latitude {site.latitude:g} deg"
            raise KeyProblems([(("window", key), message)])
        # whole seconds, inside the daylight: sunrise rounded up, sunset down
        return stamp.ceil("s") if column == SUNRISE else stamp.floor("s")

    def local(clock: dt.time, key: str) -> pd.Timestamp:
        try:
            return pd.Timestamp(dt.datetime.combine(window.date, clock)).tz_localize(
                timezone, ambiguous="raise", nonexistent="raise"
            )
        except ValueError:
            message = f"{window.date} {clock} does not exist or is ambiguous in {timezone} (daylight saving change)"
            raise KeyProblems([(("window", key), message)]) from None

    start = sun_event(SUNRISE, "start") if window.start == SUNRISE else local(cast(dt.time, window.start), "start")
    if window.duration is not None:
        end = start + pd.Timedelta(seconds=window.duration)
    elif window.end == SUNSET:
        end = sun_event(SUNSET, "end")
    else:
        end = local(cast(dt.time, window.end), "end")
    if end <= start:
        raise KeyProblems([(("window", "end"), f"must be after the start ({start}), got {end}")])
    return start, end
