"""Scenario files: the typed, validated description of one run.

A scenario is a YAML mapping; :func:`load_scenario` reads it, applies ``--set``
overrides and validates it into a :class:`Scenario` (pydantic v2). Every model
forbids unknown keys, so a typo is an error, and every problem raises
:class:`~heliostep.errors.InputError` with one line per problem naming the file,
the dotted key path and what was expected.

Example::

    name: jan21-central
    site: {latitude: 40.0, longitude: 14.25, altitude: 0.0, timezone: Europe/Rome}
    window: {date: 2025-01-21, start: "10:00", duration: 300}
    plant: {orientation: NS, azimuth_offset: 0.0, tube_height: 3.0}
    mirror: {distance: 0.0, axis: secondary, stow: hold, stow_angle: 0.0}

Sections ``name``, ``site``, ``window``, ``plant`` and ``mirror`` are required;
the others (``description``, ``transmission``, ``fmus``, ``parameters``,
``connections``, ``sequencer``, ``wind``, ``solver``, ``output``) have defaults.

YAML is read with PyYAML's safe loader changed in two ways, so that values mean
what they look like: numbers follow YAML 1.2 (``1e-6`` is a float, ``10:00`` is
the string "10:00", not the base-60 integer 600) and a key repeated in one
mapping is an error instead of silently keeping the last value.
"""

from __future__ import annotations

import datetime as dt
import re
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Annotated, Any, Literal, Union, get_args

import pandas as pd
import pvlib
import yaml
from pydantic import (
    BaseModel,
    BeforeValidator,
    ConfigDict,
    Field,
    PrivateAttr,
    ValidationError,
    field_validator,
    model_validator,
)

from heliostep.errors import InputError
from heliostep.sequencer import PATTERNS, TRIGGERS
from heliostep.geometry import (
    AXES,
    DEFAULT_MIRROR_SPACING,
    ORIENTATIONS,
    PAPER_LEVER_ARM,
    PAPER_PINION_RADIUS,
    STOW_POLICIES,
    Plant,
    Site,
    _check_timezone,
    field_distances,
)

__all__ = [
    "DEFAULT_CONNECTIONS",
    "DEFAULT_FMUS",
    "N_FIELD_MIRRORS",
    "SEQUENCER_MODES",
    "MirrorConfig",
    "OutputConfig",
    "PlantConfig",
    "Scenario",
    "SequencerConfig",
    "SiteConfig",
    "SolverConfig",
    "TransmissionConfig",
    "WindConfig",
    "WindowConfig",
    "load_scenario",
    "validate_scenario",
]

#: FMU instances of a scenario without ``fmus``: instance name -> variant name.
DEFAULT_FMUS = {"motor": "StepperMotor", "mechanics": "PanelMechanics"}
#: Connections used when a scenario gives no ``connections``: (source, target).
DEFAULT_CONNECTIONS = [
    ("motor.tau", "mechanics.tau"),
    ("mechanics.theta", "motor.theta"),
    ("mechanics.omega", "motor.omega"),
]
#: Number of end mirrors in the field; ``mirror.index`` runs from 0 to N - 1, the central one is N // 2.
N_FIELD_MIRRORS = 13
#: Energising sequences of the stepper sequencer.
SEQUENCER_MODES = tuple(PATTERNS)
SEQUENCER_TRIGGERS = tuple(TRIGGERS)

_INSTANCE_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")
_CLOCK_TIME = re.compile(r"(\d{1,2}):(\d{2})(?::(\d{2}))?")
_SUNRISE, _SUNSET = "sunrise", "sunset"
#: Top-level keys whose null value means "the defaults".
_DEFAULTED_KEYS = ("transmission", "fmus", "parameters", "sequencer", "wind", "solver", "output")


# --------------------------------------------------------------------------- YAML
class _ScenarioLoader(yaml.SafeLoader):
    """PyYAML's safe loader with YAML 1.2 numbers and an error on repeated keys."""

    def construct_mapping(self, node, deep=False):
        if isinstance(node, yaml.MappingNode):
            seen = set()
            for key_node, _ in node.value:
                if key_node.tag == "tag:yaml.org,2002:merge":
                    continue
                key = self.construct_object(key_node, deep=deep)
                try:
                    repeated = key in seen
                except TypeError:  # unhashable key: the base class reports it
                    continue
                if repeated:
                    raise yaml.constructor.ConstructorError(
                        "while constructing a mapping", node.start_mark,
                        f"found the key {key!r} twice", key_node.start_mark,
                    )
                seen.add(key)
        return super().construct_mapping(node, deep=deep)


_NUMBER_TAGS = ("tag:yaml.org,2002:int", "tag:yaml.org,2002:float")
_ScenarioLoader.yaml_implicit_resolvers = {
    first: [(tag, regexp) for tag, regexp in resolvers if tag not in _NUMBER_TAGS]
    for first, resolvers in yaml.SafeLoader.yaml_implicit_resolvers.items()
}
_ScenarioLoader.add_implicit_resolver(
    "tag:yaml.org,2002:int",
    re.compile(r"^(?:[-+]?(?:0|[1-9][0-9_]*)|0x[0-9a-fA-F_]+|0o[0-7_]+)$"),
    list("-+0123456789"),
)
_ScenarioLoader.add_implicit_resolver(
    "tag:yaml.org,2002:float",
    re.compile(
        r"""^(?:[-+]?(?:[0-9][0-9_]*\.[0-9_]*(?:[eE][-+]?[0-9]+)?
                |\.[0-9_]+(?:[eE][-+]?[0-9]+)?
                |[0-9][0-9_]*[eE][-+]?[0-9]+)
            |[-+]?\.(?:inf|Inf|INF)
            |\.(?:nan|NaN|NAN))$""",
        re.X,
    ),
    list("-+0123456789."),
)


def _octal_aware_int(loader, node):
    value = loader.construct_scalar(node).replace("_", "")
    if value.startswith("0o"):
        return int(value[2:], 8)
    return int(value, 0) if value.startswith("0x") else int(value)


_ScenarioLoader.add_constructor("tag:yaml.org,2002:int", _octal_aware_int)


def _yaml_problem(exc: yaml.YAMLError) -> str:
    mark = getattr(exc, "problem_mark", None)
    problem = getattr(exc, "problem", None) or str(exc)
    if mark is None:
        return problem
    return f"line {mark.line + 1}, column {mark.column + 1}: {problem}"


# --------------------------------------------------------------------------- validation helpers
class _KeyProblems(ValueError):
    """Problems found by a validator, each with its key path relative to the model validated."""

    def __init__(self, problems: Sequence[tuple[tuple, str]]):
        self.problems = list(problems)
        super().__init__("; ".join(f"{_dotted(path)}: {message}" for path, message in self.problems))


def _dotted(loc: Sequence) -> str:
    text = ""
    for part in loc:
        if isinstance(part, int):
            text += f"[{part}]"
        else:
            text += f".{part}" if text else str(part)
    return text


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
    return _parse_clock_time(value, _SUNRISE)


def _end_time(value):
    return None if value is None else _parse_clock_time(value, _SUNSET)


def _upper(value):
    return value.upper() if isinstance(value, str) else value


#: A real number given as a YAML number (a bool or a quoted string is an error), finite.
_Real = Annotated[float, Field(strict=True)]
_Count = Annotated[int, Field(strict=True)]


class _Section(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)


# --------------------------------------------------------------------------- sections
class SiteConfig(_Section):
    """``site``: where the plant is (see :class:`heliostep.geometry.Site`)."""

    latitude: _Real = Field(ge=-90.0, le=90.0, description="[deg], positive North")
    longitude: _Real = Field(ge=-180.0, le=180.0, description="[deg], positive East")
    altitude: _Real = Field(0.0, description="[m] above sea level")
    timezone: str = Field(description="IANA name such as 'Europe/Rome'")

    @field_validator("timezone")
    @classmethod
    def _known_timezone(cls, value: str) -> str:
        return _check_timezone(value)

    def to_site(self) -> Site:
        """The :class:`heliostep.geometry.Site` of this section."""
        return Site(latitude=self.latitude, longitude=self.longitude, altitude=self.altitude,
                    timezone=self.timezone)


class WindowConfig(_Section):
    """``window``: the simulated time span, in local time of the site.

    ``start`` is "HH:MM[:SS]" or "sunrise"; the span ends after ``duration`` [s] or
    at ``end`` ("HH:MM[:SS]" or "sunset"): exactly one of the two.
    """

    date: dt.date = Field(description="local calendar date, YYYY-MM-DD")
    start: Annotated[Union[dt.time, Literal["sunrise"]], BeforeValidator(_start_time)] = Field(
        description='local time "HH:MM" or "HH:MM:SS", or "sunrise"'
    )
    end: Annotated[Union[dt.time, Literal["sunset"], None], BeforeValidator(_end_time)] = Field(
        None, description='local time "HH:MM" or "HH:MM:SS", or "sunset"; instead of duration'
    )
    duration: _Real | None = Field(None, gt=0.0, description="[s]; instead of end")

    @model_validator(mode="after")
    def _one_way_to_end(self) -> WindowConfig:
        if (self.end is None) == (self.duration is None):
            given = "both" if self.end is not None else "neither"
            raise _KeyProblems([((), f"give exactly one of 'end' or 'duration' ({given} given)")])
        if isinstance(self.start, dt.time) and isinstance(self.end, dt.time) and self.end <= self.start:
            raise _KeyProblems([(("end",), f"must be after start ({self.start}) on the same date, "
                                           f"got {self.end}")])
        return self


class PlantConfig(_Section):
    """``plant``: the receiver line (see :class:`heliostep.geometry.Plant`)."""

    orientation: Annotated[Literal[tuple(ORIENTATIONS)], BeforeValidator(_upper)] = Field(
        "NS", description="tube direction"
    )
    azimuth_offset: _Real = Field(0.0, description="[deg], from North toward East")
    tube_height: _Real = Field(gt=0.0, description="[m] above the mirror plane")

    def to_plant(self) -> Plant:
        """The :class:`heliostep.geometry.Plant` of this section."""
        return Plant(tube_height=self.tube_height, orientation=self.orientation,
                     azimuth_offset=self.azimuth_offset)


class MirrorConfig(_Section):
    """``mirror``: which end mirror is driven and how it tracks.

    Its position is ``distance`` [m] from the tube, or ``index`` (0 .. 12, 6 is the
    central mirror) in the field of 13 mirrors ``spacing`` [m] apart: exactly one of
    ``distance`` and ``index``.
    """

    distance: _Real | None = Field(None, description="[m], transverse position; instead of index")
    index: _Count | None = Field(None, ge=0, le=N_FIELD_MIRRORS - 1,
                                 description="position in the field of 13; instead of distance")
    spacing: _Real | None = Field(None, gt=0.0, description=f"[m] between mirrors, with index "
                                                            f"(default {DEFAULT_MIRROR_SPACING})")
    axis: Literal[AXES] = Field("secondary", description="the driven axis")
    stow: Literal[STOW_POLICIES] = Field("hold", description="policy while the sun is down")
    stow_angle: _Real = Field(0.0, ge=-90.0, le=90.0, description="[deg]")

    @model_validator(mode="after")
    def _one_position(self) -> MirrorConfig:
        if (self.distance is None) == (self.index is None):
            given = "both" if self.index is not None else "neither"
            raise _KeyProblems([((), f"give exactly one of 'distance' or 'index' ({given} given)")])
        if self.spacing is not None and self.index is None:
            raise _KeyProblems([(("spacing",), "only applies with 'index'; remove it or give 'index' "
                                               "instead of 'distance'")])
        return self

    @property
    def mirror_distance(self) -> float:
        """Transverse position of the mirror [m]: ``distance`` or the index's place in the field."""
        if self.distance is not None:
            return self.distance
        spacing = DEFAULT_MIRROR_SPACING if self.spacing is None else self.spacing
        return float(field_distances(N_FIELD_MIRRORS, spacing)[self.index])


class TransmissionConfig(_Section):
    """``transmission``: rack and pinion between rotor and panel (defaults: the paper's Table 2)."""

    pinion_radius: _Real = Field(PAPER_PINION_RADIUS, gt=0.0, description="[m]")
    lever_arm: _Real = Field(PAPER_LEVER_ARM, gt=0.0, description="[m]")


class SequencerConfig(_Section):
    """``sequencer``: how the stepper's phases are energised."""

    mode: Literal[SEQUENCER_MODES] = Field("one-phase-on", description="energising sequence")
    current: _Real = Field(5.5, gt=0.0, description="[A], phase current")
    step_angle: _Real = Field(1.8, gt=0.0, description="[deg], full step of the rotor")
    trigger: Literal[SEQUENCER_TRIGGERS] = Field(
        "midpoint", description="step when the reference crosses the midpoint to the next position, or reaches it")


class WindConfig(_Section):
    """``wind``: external load on the panel."""

    moment: _Real = Field(0.0, description="[N.m], constant moment on the panel")


class SolverConfig(_Section):
    """``solver``: settings of the master's ODE solver."""

    rtol: _Real = Field(1.0e-6, gt=0.0, le=0.1, description="relative tolerance")
    atol: _Real | None = Field(None, gt=0.0, description="absolute tolerance, null: the solver's default")
    max_step: _Real | None = Field(None, gt=0.0, description="[s], null: no limit")
    max_num_steps: _Count = Field(100_000, gt=0, description="solver steps at most")


class OutputConfig(_Section):
    """``output``: time grid of the trace."""

    interval: _Real = Field(0.01, gt=0.0, description="[s], spacing of the regular grid")
    step_detail: _Real = Field(0.05, gt=0.0, description="[s] after each step kept on the fine grid")
    step_interval: _Real = Field(0.0005, gt=0.0, description="[s], spacing of the fine grid")


def _merge_default_fmus(value):
    """Entries of ``fmus`` over :data:`DEFAULT_FMUS`; a null entry drops that instance."""
    if not isinstance(value, Mapping):
        return value
    merged = {**DEFAULT_FMUS, **value}
    return {name: variant for name, variant in merged.items() if variant is not None}


def _connection_pair(value):
    if isinstance(value, (list, tuple)) and len(value) == 2 and all(isinstance(v, str) for v in value):
        return tuple(value)
    raise ValueError(f"expected a [source, target] pair of 'instance.variable' strings, got {value!r}")


def _endpoint_problem(endpoint: str) -> str | None:
    instance, dot, variable = endpoint.partition(".")
    if not dot or not variable or not _INSTANCE_NAME.fullmatch(instance):
        return f"expected 'instance.variable' (e.g. 'motor.tau'), got {endpoint!r}"
    return None


# --------------------------------------------------------------------------- scenario
class Scenario(_Section):
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
    parameters: dict[str, dict[str, _Real]] = Field(
        default_factory=dict, description="instance name -> {parameter name: value}"
    )
    connections: list[Annotated[tuple[str, str], BeforeValidator(_connection_pair)]] | None = Field(
        None, description="[source, target] pairs 'instance.variable'; null: the default connections"
    )
    sequencer: SequencerConfig = Field(default_factory=SequencerConfig)
    wind: WindConfig = Field(default_factory=WindConfig)
    solver: SolverConfig = Field(default_factory=SolverConfig)
    output: OutputConfig = Field(default_factory=OutputConfig)

    _folder: Path = PrivateAttr(default_factory=Path.cwd)
    _source: str = PrivateAttr(default="<scenario>")

    @model_validator(mode="before")
    @classmethod
    def _empty_means_default(cls, data):
        """An empty (null) section takes its defaults, e.g. ``wind:`` with its lines commented out."""
        if not isinstance(data, Mapping):
            return data
        data = {key: value for key, value in data.items() if not (value is None and key in _DEFAULTED_KEYS)}
        if isinstance(data.get("parameters"), Mapping):
            data["parameters"] = {instance: {} if values is None else values
                                  for instance, values in data["parameters"].items()}
        return data

    @field_validator("name")
    @classmethod
    def _not_blank(cls, value: str) -> str:
        if not value.strip():
            raise ValueError("must not be blank")
        return value.strip()

    @field_validator("fmus")
    @classmethod
    def _fmu_names(cls, fmus: dict[str, str]) -> dict[str, str]:
        problems = []
        if not fmus:
            problems.append(((), "at least one FMU instance is needed"))
        for instance, variant in fmus.items():
            if not _INSTANCE_NAME.fullmatch(instance):
                problems.append(((instance,), "instance names are identifiers (letters, digits, '_', "
                                              "not starting with a digit)"))
            if not variant.strip():
                problems.append(((instance,), "expected a model variant name or a path to an .fmu, got ''"))
        if problems:
            raise _KeyProblems(problems)
        return fmus

    @field_validator("connections")
    @classmethod
    def _connection_endpoints(cls, connections):
        if connections is None:
            return None
        problems = []
        for position, pair in enumerate(connections):
            for side, endpoint in enumerate(pair):
                problem = _endpoint_problem(endpoint)
                if problem:
                    problems.append(((position, side), problem))
            if pair[0] == pair[1]:
                problems.append(((position,), f"connects {pair[0]!r} to itself"))
        if problems:
            raise _KeyProblems(problems)
        return connections

    @model_validator(mode="after")
    def _consistent_sections(self) -> Scenario:
        problems = []
        instances = ", ".join(self.fmus)
        for instance in self.parameters:
            if instance not in self.fmus:
                problems.append((("parameters", instance), f"unknown FMU instance; instances in fmus: {instances}"))
        if self.connections is None:
            missing = sorted({endpoint.partition(".")[0] for pair in DEFAULT_CONNECTIONS for endpoint in pair}
                             - set(self.fmus))
            if missing:
                problems.append((("connections",), f"the default connections use FMU instance(s) "
                                                   f"{', '.join(missing)}, not in fmus ({instances}); "
                                                   f"give 'connections' explicitly ([] for none)"))
        else:
            targets = {}
            for position, (source, target) in enumerate(self.connections):
                for side, endpoint in enumerate((source, target)):
                    instance = endpoint.partition(".")[0]
                    if instance not in self.fmus:
                        problems.append((("connections", position, side), f"{endpoint!r}: unknown FMU instance "
                                                                          f"{instance!r}; instances in fmus: {instances}"))
                if target in targets:
                    problems.append((("connections", position), f"{target!r} is already the target of "
                                                                f"connections[{targets[target]}]; an input has one source"))
                targets.setdefault(target, position)
        try:
            self._resolve_window()
        except _KeyProblems as exc:
            problems += exc.problems
        if problems:
            raise _KeyProblems(problems)
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
        return [tuple(pair) for pair in pairs]

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
            raise InputError(f"{self._source}: fmus: no FMU instance {instance!r}; "
                             f"instances: {', '.join(self.fmus)}")
        reference = self.fmus[instance]
        if "/" not in reference and "\\" not in reference and not reference.lower().endswith(".fmu"):
            return reference
        path = Path(reference).expanduser()
        return path if path.is_absolute() else (self._folder / path).resolve()

    def window_bounds(self) -> tuple[pd.Timestamp, pd.Timestamp]:
        """Start and end of the simulated window.

        "sunrise" and "sunset" are computed with NREL's SPA
        (:func:`pvlib.solarposition.sun_rise_set_transit_spa`) for the window's date
        and the site.

        Returns
        -------
        start, end : pandas.Timestamp
            Timezone-aware, in the site's timezone.
        """
        try:
            return self._resolve_window()
        except _KeyProblems as exc:
            raise InputError("\n".join(f"{self._source}: {_dotted(path)}: {message}"
                                       for path, message in exc.problems)) from None

    def resolved_dict(self) -> dict:
        """The fully validated scenario as plain JSON-able data (for run metadata).

        Defaults are filled in, ``fmus`` is merged over :data:`DEFAULT_FMUS` and
        ``connections`` is the effective list; reading it back gives an equal scenario.
        """
        data = self.model_dump(mode="json")
        data["connections"] = [list(pair) for pair in self.connection_pairs()]
        return data

    @property
    def folder(self) -> Path:
        """Folder that relative FMU paths are resolved against."""
        return self._folder

    # ----------------------------------------------------------------------- helpers
    def _resolve_window(self) -> tuple[pd.Timestamp, pd.Timestamp]:
        timezone = self.site.timezone
        window = self.window
        events = None

        def sun_event(column: str, key: str) -> pd.Timestamp:
            nonlocal events
            if events is None:
                noon = pd.DatetimeIndex([pd.Timestamp(dt.datetime.combine(window.date, dt.time(12)))])
                events = pvlib.solarposition.sun_rise_set_transit_spa(
                    noon.tz_localize(timezone), self.site.latitude, self.site.longitude
                )
            stamp = events[column].iloc[0]
            if pd.isna(stamp):
                raise _KeyProblems([(("window", key), f"the sun has no {column} on {window.date} at "
                                                      f"latitude {self.site.latitude:g} deg")])
            stamp = pd.Timestamp(stamp).tz_convert(timezone)
            # whole seconds, inside the daylight: sunrise rounded up, sunset down
            return stamp.ceil("s") if column == _SUNRISE else stamp.floor("s")

        def local(clock: dt.time, key: str) -> pd.Timestamp:
            try:
                return pd.Timestamp(dt.datetime.combine(window.date, clock)).tz_localize(
                    timezone, ambiguous="raise", nonexistent="raise"
                )
            except ValueError:
                raise _KeyProblems([(("window", key), f"{window.date} {clock} does not exist or is "
                                                      f"ambiguous in {timezone} (daylight saving change)")]) from None

        start = sun_event(_SUNRISE, "start") if window.start == _SUNRISE else local(window.start, "start")
        if window.duration is not None:
            end = start + pd.Timedelta(seconds=window.duration)
        elif window.end == _SUNSET:
            end = sun_event(_SUNSET, "end")
        else:
            end = local(window.end, "end")
        if end <= start:
            raise _KeyProblems([(("window", "end"), f"must be after the start ({start}), got {end}")])
        return start, end


# --------------------------------------------------------------------------- errors
def _model_of(annotation) -> type[BaseModel] | None:
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return annotation
    for argument in get_args(annotation):
        model = _model_of(argument)
        if model is not None:
            return model
    return None


def _field_at(loc: Sequence):
    """(model holding the last key, its FieldInfo) for a key path, as far as models reach."""
    model, info = Scenario, None
    for depth, part in enumerate(loc):
        if model is None or part not in model.model_fields:
            return (model if depth == len(loc) - 1 else None), None
        info = model.model_fields[part]
        if depth < len(loc) - 1:
            model = _model_of(info.annotation)
    return model, info


def _explain(error: dict) -> list[tuple[tuple, str]]:
    """(key path, message) lines for one pydantic error."""
    loc, kind = tuple(error["loc"]), error["type"]
    cause = (error.get("ctx") or {}).get("error")
    if isinstance(cause, _KeyProblems):
        return [(loc + path, message) for path, message in cause.problems]
    if cause is not None:
        return [(loc, str(cause))]
    model, info = _field_at(loc)
    meaning = f" ({info.description})" if info is not None and info.description else ""
    if kind == "extra_forbidden":
        allowed = f"; allowed keys: {', '.join(model.model_fields)}" if model is not None else ""
        return [(loc, f"unknown key{allowed}")]
    if kind == "missing":
        return [(loc, f"required key is missing{meaning}")]
    if kind == "literal_error":
        return [(loc, f"expected one of {error['ctx']['expected']}, got {error['input']!r}")]
    return [(loc, f"{error['msg']}{meaning}, got {error['input']!r}")]


def _format_validation_error(exc: ValidationError, source: str) -> str:
    lines = []
    for error in exc.errors(include_url=False):
        for loc, message in _explain(error):
            lines.append(f"{source}: {_dotted(loc) or '(top level)'}: {message}")
    return "\n".join(lines)


# --------------------------------------------------------------------------- loading
def _apply_overrides(data: dict, overrides: Sequence[str], source: str) -> dict:
    """Set ``"dotted.key=value"`` overrides in ``data`` (in place); values are YAML."""
    for override in overrides:
        if not isinstance(override, str):
            raise InputError(f"{source}: --set {override!r}: expected a string 'dotted.key=value'")
        key, equals, text = override.partition("=")
        parts = key.strip().split(".")
        if not equals or not all(part.strip() for part in parts):
            raise InputError(f"{source}: --set {override!r}: expected 'dotted.key=value', "
                             f"e.g. 'sequencer.current=3'")
        parts = [part.strip() for part in parts]
        try:
            value = yaml.load(text, Loader=_ScenarioLoader)  # noqa: S506 - a SafeLoader
        except yaml.YAMLError as exc:
            raise InputError(f"{source}: --set {override!r}: the value is not valid YAML: "
                             f"{_yaml_problem(exc)}") from None
        set_dotted_key(data, parts, value, f"{source}: --set {override!r}")
    return data


def set_dotted_key(data: dict, parts: Sequence[str], value, where: str) -> None:
    """Set ``data[parts[0]][parts[1]]... = value``, creating missing mappings on the way.

    A part that is already something other than a mapping is an :class:`InputError`
    starting with ``where``.
    """
    node = data
    for depth, part in enumerate(parts[:-1]):
        child = node.get(part)
        if child is None:
            child = node[part] = {}
        elif not isinstance(child, dict):
            raise InputError(f"{where}: {'.'.join(parts[:depth + 1])} is {child!r}, not a mapping, "
                             f"so it has no key {parts[depth + 1]!r}")
        node = child
    node[parts[-1]] = value


def validate_scenario(data: Mapping, *, source: str = "<scenario>", folder=None) -> Scenario:
    """Validate a scenario mapping.

    Parameters
    ----------
    data : Mapping
        The scenario, as read from YAML.
    source : str, default "<scenario>"
        Named in error messages (the file).
    folder : str or Path, optional
        Folder that relative FMU paths resolve against; default the current directory.

    Returns
    -------
    Scenario

    Raises
    ------
    InputError
        One line per problem: source, dotted key path, what was expected.
    """
    if not isinstance(data, Mapping):
        raise InputError(f"{source}: the top level must be a mapping of keys (name, site, window, ...), "
                         f"got {type(data).__name__}")
    try:
        scenario = Scenario.model_validate(dict(data))
    except ValidationError as exc:
        raise InputError(_format_validation_error(exc, source)) from None
    scenario._folder = Path.cwd() if folder is None else Path(folder).absolute()
    scenario._source = source
    return scenario


def read_yaml_file(path: str | Path, what: str):
    """Read a YAML file the way heliostep reads scenarios (and sweeps).

    YAML 1.2 numbers (``1e-6`` is a float), clock times such as ``10:00`` kept as strings,
    a key repeated in one mapping refused. Every problem is an :class:`InputError` naming
    the file (``what`` says which kind of file it is).
    """
    source = str(path)
    try:
        text = Path(path).read_text(encoding="utf-8")
    except FileNotFoundError:
        raise InputError(f"{source}: {what} file not found") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"{source}: cannot read the {what} file: {exc}") from None
    try:
        return yaml.load(text, Loader=_ScenarioLoader)  # noqa: S506 - a SafeLoader
    except yaml.YAMLError as exc:
        raise InputError(f"{source}: not valid YAML: {_yaml_problem(exc)}") from None


def load_scenario(path, overrides: Sequence[str] = ()) -> Scenario:
    """Read, override and validate a scenario file.

    Parameters
    ----------
    path : str or Path
        YAML scenario file.
    overrides : sequence of str, default ()
        ``"dotted.key=value"`` items (the command line's ``--set``), applied in order
        before validation. The value is YAML (``sequencer.current=3`` is a number,
        ``fmus.motor=StepperMotorIdealCurrent`` a string, ``fmus.mechanics=`` null);
        missing intermediate mappings are created.

    Returns
    -------
    Scenario
        Relative FMU paths resolve against the file's folder.

    Raises
    ------
    InputError
        Missing or unreadable file, invalid YAML (with its line), a top level that is
        not a mapping, a malformed override, or an invalid scenario (one line per
        problem, each naming the file, the key path and what was expected).
    """
    if isinstance(overrides, str):
        raise TypeError("overrides must be a sequence of 'dotted.key=value' strings, not one string")
    path = Path(path)
    source = str(path)
    data = read_yaml_file(path, "scenario")
    if not isinstance(data, dict):
        what = "empty" if data is None else f"a {type(data).__name__}"
        raise InputError(f"{source}: the top level must be a mapping of keys (name, site, window, ...), "
                         f"the file holds {what}")
    data = _apply_overrides(data, overrides, source)
    return validate_scenario(data, source=source, folder=path.absolute().parent)
