"""Sweep files and their cases: combinations of the axes (:mod:`heliostep.sweep.axes`), each case's
validated scenario and identity."""

from __future__ import annotations

import copy
import dataclasses
import hashlib
import itertools
import json
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any

from heliostep.errors import InputError
from heliostep.scenario import (
    Scenario,
    load_scenario,
    read_yaml_file,
    set_dotted_key,
    validate_scenario,
)
from heliostep.solar import N_FIELD_MIRRORS
from heliostep.solar.field import PRIMARY_LEVER_ARM, primary_panel_inertia
from heliostep.sweep.axes import (
    CENTRAL_MIRROR,
    SHORTHAND_AXES,
    SweepAxis,
    axis_hint,
    catalogue_path,
    check_axis_key,
    check_case_count,
    make_axis,
    setting_by_role,
    show_value,
    table_value,
)

__all__ = [
    "CENTRAL_MIRROR",
    "COMBINE_MODES",
    "ROLES",
    "SHIPPED_MECHANICS",
    "SHORTHAND_AXES",
    "SweepAxis",
    "SweepCase",
    "SweepSpec",
    "MAX_CASES",
    "expand_cases",
    "load_sweep",
    "sweep_from_scenario",
    "sweep_metadata",
]

#: How the axes combine into cases.
COMBINE_MODES = ("product", "zip")


#: Mechanics models whose panel inertia and lever arm the shared primary's case sets.
SHIPPED_MECHANICS = ("PanelMechanics", "PanelMechanicsSmallAngle", "PanelMechanicsKarnopp")


def _primary_load(base: Mapping) -> list[tuple[str, Any]]:
    """The shared primary drive's own load: all the field's panels about their longitudinal axes
    (:func:`heliostep.solar.field.primary_panel_inertia`) through the primary's rack
    (:data:`heliostep.solar.field.PRIMARY_LEVER_ARM`). Set for the shipped mechanics models; a
    user's own mechanics FMU keeps its parameters (give them in the sweep's overrides)."""
    instance = str((base.get("roles") or {}).get("panel_angle") or "mechanics.theta_p").partition(".")[0]
    if (base.get("fmus") or {}).get(instance) not in SHIPPED_MECHANICS:
        return []
    return [
        ("transmission.lever_arm", PRIMARY_LEVER_ARM),
        (f"parameters.{instance}.J_p", primary_panel_inertia(N_FIELD_MIRRORS)),
    ]


#: Roles of a case: one mirror's drive, or the field's shared primary drive.
ROLES = ("drive", "shared-primary")


_SWEEP_KEYS = tuple("name description base combine axes overrides shared_primary max_cases catalogue".split())

#: The most cases a sweep may have unless its file says ``max_cases`` (each case is a run; the
#: cases are counted from the axes before any is built).
MAX_CASES = 10_000


@dataclasses.dataclass(frozen=True)
class SweepSpec:
    """A parsed sweep (see the module docstring); build it with :func:`load_sweep`.

    Attributes
    ----------
    name : str
    source : str
        The sweep file (or a description), named in error messages.
    base_data : dict
        The base scenario as plain data (its resolved form).
    base_source : str
        The base scenario's file, named in error messages.
    base_folder : Path
        Folder that relative FMU paths of the base scenario resolve against.
    axes : tuple of SweepAxis
    combine : {"product", "zip"}
    overrides : tuple of (str, object)
        (dotted key, value) applied to every case, before the axes.
    shared_primary : bool
        Add, per combination of the other axes, one case of the field's shared primary
        drive (the central mirror's primary axis); needs a ``mirror`` axis.
    description : str or None
    max_cases : int
        The most cases the axes may give.
    file : str or None
        The sweep file's absolute path (None for a sweep built in Python): the sweep's identity in
        its results table.
    """

    name: str
    source: str
    base_data: dict
    base_source: str
    base_folder: Path
    axes: tuple[SweepAxis, ...]
    combine: str = "product"
    overrides: tuple[tuple[str, Any], ...] = ()
    shared_primary: bool = False
    description: str | None = None
    max_cases: int = MAX_CASES
    file: str | None = None


@dataclasses.dataclass(frozen=True)
class SweepCase:
    """One case of a sweep: a validated scenario and its row's identity columns.

    Attributes
    ----------
    case_id : str
        16 hex digits of the SHA-256 of the resolved scenario: stable across reruns.
    index : int
        Position in the sweep's expansion.
    columns : dict
        Identity and parameter columns of the case's row (axis values, date, mirror, ...).
    scenario : dict
        The case's resolved scenario (JSON-able); ``fmus`` holds variant names or
        absolute paths.
    source : str
        Named in the case's error messages.
    folder : str
        The base scenario's folder.
    fmu_sha256 : dict
        FMU instance -> SHA-256 of the FMU file the case runs (set by :func:`execute_cases`).
    """

    case_id: str
    index: int
    columns: dict
    scenario: dict
    source: str
    folder: str
    fmu_sha256: dict = dataclasses.field(default_factory=dict)

    @property
    def label(self) -> str:
        """A short description: the case's override settings."""
        return self.columns.get("overrides") or "(base)"


def load_sweep(path: str | Path) -> SweepSpec:
    """Read and check a sweep file (its cases are built by :func:`expand_cases`).

    Parameters
    ----------
    path : str or Path
        The sweep YAML.

    Returns
    -------
    SweepSpec

    Raises
    ------
    InputError
        Naming the sweep file and key: unreadable file, unknown key, missing base,
        an empty axis, a repeated value, zip axes of different lengths, an invalid
        ``day_of_year`` or ``mirror`` value, or an invalid base scenario.
    """
    path = Path(path)
    source = str(path)
    data = read_yaml_file(path, "sweep")
    if not isinstance(data, dict):
        raise InputError(f"{source}: the top level must be a mapping with keys {', '.join(_SWEEP_KEYS)}")
    unknown = [key for key in data if key not in _SWEEP_KEYS]
    if unknown:
        raise InputError(f"{source}: {unknown[0]}: unknown key; allowed keys: {', '.join(_SWEEP_KEYS)}")
    if not isinstance(data.get("base"), str) or not data["base"].strip():
        raise InputError(f"{source}: base: required: the path of the base scenario (relative to the sweep file)")
    base_path = Path(data["base"]).expanduser()
    if not base_path.is_absolute():
        base_path = path.absolute().parent / base_path
    try:
        base = load_scenario(base_path)
    except InputError as exc:
        raise InputError(f"{source}: base: {exc}") from None
    name = data.get("name", path.stem)
    if not isinstance(name, str) or not name.strip() or any(c in name for c in "/\\") or name.startswith("."):
        raise InputError(
            f"{source}: name: expected a non-empty name usable as a folder name "
            f"(no '/', not starting with '.'), got {name!r}"
        )
    return _make_spec(
        name=name.strip(),
        source=source,
        base=base,
        base_source=str(base_path),
        axes=data.get("axes"),
        combine=data.get("combine", "product"),
        overrides=data.get("overrides"),
        shared_primary=data.get("shared_primary", False),
        description=data.get("description"),
        max_cases=data.get("max_cases", MAX_CASES),
        file=str(path.resolve()),
        catalogue=catalogue_path(data, path, f"{source}: catalogue"),
    )


def sweep_from_scenario(
    scenario: Scenario,
    axes: Mapping[str, Any],
    *,
    combine: str = "product",
    overrides: Mapping[str, Any] | None = None,
    shared_primary: bool = False,
    name: str | None = None,
    source: str | None = None,
) -> SweepSpec:
    """A sweep over an in-memory scenario (the Python form of a sweep file).

    Parameters
    ----------
    scenario : Scenario
        The base scenario.
    axes : Mapping
        Axis name (shorthand or dotted key) -> values (a list, "all" or ``{start, stop, step}``).
    combine : {"product", "zip"}, default "product"
    overrides : Mapping, optional
        Dotted key -> value, applied to every case.
    shared_primary : bool, default False
        See :class:`SweepSpec`.
    name : str, optional
        Default: the scenario's name.
    source : str, optional
        Named in error messages; default ``"sweep of <scenario name>"``.

    Returns
    -------
    SweepSpec
    """
    label = source or f"sweep of {scenario.name}"
    return _make_spec(
        name=name or scenario.name,
        source=label,
        base=scenario,
        base_source=f"scenario {scenario.name}",
        axes=axes,
        combine=combine,
        overrides=overrides,
        shared_primary=shared_primary,
        description=None,
    )


def _make_spec(
    *,
    name,
    source,
    base: Scenario,
    base_source,
    axes,
    combine,
    overrides,
    shared_primary,
    description,
    max_cases=MAX_CASES,
    file=None,
    catalogue=None,
) -> SweepSpec:
    if combine not in COMBINE_MODES:
        raise InputError(f"{source}: combine: expected one of {', '.join(COMBINE_MODES)}, got {combine!r}")
    if not isinstance(shared_primary, bool):
        raise InputError(f"{source}: shared_primary: expected true or false, got {shared_primary!r}")
    if description is not None and not isinstance(description, str):
        raise InputError(f"{source}: description: expected a string, got {description!r}")
    if isinstance(max_cases, bool) or not isinstance(max_cases, int) or max_cases < 1:
        raise InputError(f"{source}: max_cases: expected a whole number of cases >= 1, got {max_cases!r}")
    if overrides is None:
        overrides = {}
    if not isinstance(overrides, Mapping):
        raise InputError(
            f"{source}: overrides: expected a mapping of dotted scenario keys to values, "
            f"e.g. {{output.interval: 0.5}}, got {overrides!r}"
        )
    common = tuple((check_axis_key(key, f"{source}: overrides"), value) for key, value in overrides.items())
    base_data = base.resolved_dict()
    base_data["fmus"] = {
        instance: None if reference is None else str(base.fmu_reference(instance))
        for instance, reference in base_data["fmus"].items()
    }
    spec = SweepSpec(
        name=name,
        source=source,
        base_data=base_data,
        base_source=base_source,
        base_folder=base.folder,
        axes=(),
        combine=combine,
        overrides=common,
        shared_primary=shared_primary,
        description=description,
        max_cases=max_cases,
        file=file,
    )
    scenario = _validated(spec, (), f"{source}: overrides")  # the base as the axes see it (its roles, its year)
    parsed = _parsed_axes(axes, source, scenario, catalogue, combine, shared_primary)
    return dataclasses.replace(spec, axes=parsed)


def _parsed_axes(axes, source: str, base: Scenario, catalogue, combine: str, shared_primary: bool) -> tuple:
    """The sweep's axes from their raw form (:func:`~heliostep.sweep.axes.make_axis`), checked: at least one, no
    two setting one key, equal lengths for ``zip``, a ``mirror`` axis for ``shared_primary``."""
    if not isinstance(axes, Mapping) or not axes:
        raise InputError(
            f"{source}: axes: expected a mapping of at least one axis (e.g. day_of_year: [21, 172]), got {axes!r}"
        )
    year = base.window.date.year
    parsed = tuple(make_axis(name, raw, year, f"{source}: axes", base, catalogue) for name, raw in axes.items())
    owner: dict[str, str] = {}  # dotted key -> the axis that sets it
    for axis in parsed:
        for key, _ in axis.overrides(axis.values[0], year):
            if key in owner and key != "mirror.distance":
                raise InputError(f"{source}: axes.{axis.name}: sets {key}, as axes.{owner[key]} does")
            owner.setdefault(key, axis.name)
    if combine == "zip":
        lengths = {axis.name: len(axis.values) for axis in parsed}
        if len(set(lengths.values())) > 1:
            listed = ", ".join(f"{axis_name} has {n}" for axis_name, n in lengths.items())
            raise InputError(f"{source}: axes: combine: zip needs axes of equal length; {listed} values")
    if shared_primary and "mirror" not in [axis.name for axis in parsed]:
        raise InputError(f"{source}: shared_primary: needs a 'mirror' axis (e.g. mirror: all)")
    return parsed


def _set_dotted(data: dict, key: str, value, where: str) -> None:
    set_dotted_key(data, key.split("."), copy.deepcopy(value), where)


def _scenario_data(spec: SweepSpec, settings: Iterable[tuple[str, Any]], where: str) -> dict:
    data = copy.deepcopy(spec.base_data)
    for key, value in (*spec.overrides, *settings):
        _set_dotted(data, key, value, where)
    return data


def _validated(spec: SweepSpec, settings: Sequence[tuple[str, Any]], where: str, hint: str = "") -> Scenario:
    """The base scenario with the sweep's and ``settings``' overrides, validated."""
    data = _scenario_data(spec, settings, where)
    shown = ", ".join(f"{key}={show_value(value)}" for key, value in settings)
    try:
        return validate_scenario(
            data, source=f"{spec.base_source}{' with ' + shown if shown else ''}", folder=spec.base_folder
        )
    except InputError as exc:
        raise InputError(f"{where}: gives an invalid scenario{hint}:\n{exc}") from None


def expand_cases(spec: SweepSpec) -> list[SweepCase]:
    """All cases of a sweep, each with its scenario validated.

    Parameters
    ----------
    spec : SweepSpec

    Returns
    -------
    list of SweepCase
        In expansion order (``product``: the first axis varies slowest), then the shared
        primary cases when ``spec.shared_primary``.

    Raises
    ------
    InputError
        When a case's scenario is invalid (naming the sweep file and the case's
        settings), or when two cases are the same scenario.
    """
    check_case_count(spec.source, spec.axes, spec.combine, spec.shared_primary, spec.max_cases)  # before any is built
    year = _validated(spec, (), f"{spec.source}: overrides").window.date.year
    if spec.combine == "zip":
        combinations = list(zip(*(axis.values for axis in spec.axes)))
    else:
        combinations = list(itertools.product(*(axis.values for axis in spec.axes)))
    cases: list[SweepCase] = []
    for values in combinations:
        cases.append(_make_case(spec, year, dict(zip(spec.axes, values)), len(cases), "drive"))
    if spec.shared_primary:
        others = [axis for axis in spec.axes if axis.name != "mirror"]
        seen = set()
        for values in combinations:
            chosen = {axis: value for axis, value in zip(spec.axes, values) if axis.name != "mirror"}
            key = json.dumps([show_value(chosen[axis]) for axis in others])
            if key not in seen:
                seen.add(key)
                cases.append(_make_case(spec, year, chosen, len(cases), "shared-primary"))
    first_of: dict[str, SweepCase] = {}
    for case in cases:
        if case.case_id in first_of:
            other = first_of[case.case_id]
            raise InputError(
                f"{spec.source}: axes: cases {other.index} ({other.label}) and {case.index} "
                f"({case.label}) are the same scenario"
            )
        first_of[case.case_id] = case
    return cases


def _make_case(spec: SweepSpec, year: int, chosen: Mapping[SweepAxis, Any], index: int, role: str) -> SweepCase:
    """One validated case: the axis values ``chosen`` on the base, as a drive or the shared primary."""
    if role not in ROLES:
        raise ValueError(f"role must be one of {ROLES}, got {role!r}")
    settings = [
        setting_by_role(setting, axis.name, spec.base_data)
        for axis, value in chosen.items()
        for setting in axis.overrides(value, year)
    ]
    if role == "shared-primary":
        settings += [("mirror.distance", None), ("mirror.index", CENTRAL_MIRROR), ("mirror.axis", "primary")]
        settings += _primary_load(spec.base_data)
    shown = ", ".join(f"{axis.name}={show_value(value)}" for axis, value in chosen.items())
    if role == "shared-primary":
        shown += " (shared primary)"
    try:
        scenario = _validated(spec, settings, f"{spec.source}: case {index} ({shown})")
    except InputError:
        for axis, value in chosen.items():  # name the axis when its value alone is invalid
            _validated(
                spec,
                axis.overrides(value, year),
                f"{spec.source}: axes.{axis.name}: {show_value(value)}",
                hint=axis_hint(axis.name),
            )
        raise
    resolved = scenario.resolved_dict()
    resolved["fmus"] = {
        instance: None if reference is None else str(scenario.fmu_reference(instance))
        for instance, reference in resolved["fmus"].items()
    }
    case_id = hashlib.sha256(json.dumps(resolved, sort_keys=True).encode()).hexdigest()[:16]
    mirror = scenario.mirror
    columns = {
        "case_id": case_id,
        "case_index": index,
        "role": role,
        **{axis.column: table_value(value) for axis, value in chosen.items()},
        "date": scenario.window.date.isoformat(),
        "day_of_year": scenario.window.date.timetuple().tm_yday,
        "mirror_index": mirror.index,
        "mirror_distance_m": float(mirror.mirror_distance),
        "mirror_axis": mirror.axis,
        "motor": scenario.fmus.get(scenario.roles.instance_of("torque") or ""),
        "mechanics": scenario.fmus.get(scenario.roles.instance_of("rotor_angle") or ""),
        "current_A": scenario.sequencer.current,
        "wind_moment_Nm": scenario.wind.moment,
        "overrides": ", ".join(f"{key}={show_value(value)}" for key, value in (*spec.overrides, *settings)),
    }
    return SweepCase(
        case_id=case_id,
        index=index,
        columns=columns,
        scenario=resolved,
        source=f"{spec.source}: case {index} ({shown})",
        folder=str(spec.base_folder),
    )


def sweep_metadata(spec: SweepSpec) -> dict:
    """What the table's Parquet metadata records about the sweep (name, file, source, axes, combine)."""
    return {
        "name": spec.name,
        "file": spec.file,
        "source": spec.source,
        "base": spec.base_source,
        "combine": spec.combine,
        "axes": {axis.name: axis.column for axis in spec.axes},
        "shared_primary": spec.shared_primary,
        "overrides": {key: show_value(value) for key, value in spec.overrides},
    }
