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

Modules: :mod:`~heliostep.scenario.yaml_io` (the YAML reader), :mod:`~heliostep.scenario.keys`
(dotted keys, ``--set``), :mod:`~heliostep.scenario.sections` and :mod:`~heliostep.scenario.model`
(the typed models), :mod:`~heliostep.scenario.problems` (error lines) and
:mod:`~heliostep.scenario.load`. This package imports only the layers below it (the contracts in
``pyproject.toml``): :mod:`heliostep.solar` (sites, plants, field geometry, sun events),
:mod:`heliostep.cosim.signals` (the solver options' defaults), :mod:`heliostep.fmu.reference`
(which FMU references are variant names), and :mod:`heliostep.errors` and :mod:`heliostep.paths`
(the shipped scenarios' folder).
"""

from heliostep.scenario.keys import KeyProblems, apply_overrides, dotted, set_dotted_key
from heliostep.scenario.load import (
    load_scenario,
    resolve_scenario_path,
    shipped_scenario_dir,
    validate_scenario,
)
from heliostep.scenario.model import DEFAULT_CONNECTIONS, DEFAULT_FMUS, Scenario
from heliostep.scenario.roles import (
    INPUT_ROLES,
    OUTPUT_ROLES,
    PARAMETER_ROLES,
    REQUIRED_ROLES,
    RolesConfig,
)
from heliostep.scenario.sections import (
    SEQUENCER_MODES,
    SEQUENCER_TRIGGERS,
    MirrorConfig,
    OutputConfig,
    PlantConfig,
    SequencerConfig,
    SiteConfig,
    SolverConfig,
    TransmissionConfig,
    WindConfig,
    WindowConfig,
)
from heliostep.scenario.yaml_io import parse_yaml_value, read_yaml_file, yaml_problem

__all__ = [
    "DEFAULT_CONNECTIONS",
    "DEFAULT_FMUS",
    "INPUT_ROLES",
    "OUTPUT_ROLES",
    "PARAMETER_ROLES",
    "REQUIRED_ROLES",
    "SEQUENCER_MODES",
    "SEQUENCER_TRIGGERS",
    "KeyProblems",
    "MirrorConfig",
    "OutputConfig",
    "PlantConfig",
    "RolesConfig",
    "Scenario",
    "SequencerConfig",
    "SiteConfig",
    "SolverConfig",
    "TransmissionConfig",
    "WindConfig",
    "WindowConfig",
    "apply_overrides",
    "dotted",
    "load_scenario",
    "parse_yaml_value",
    "read_yaml_file",
    "resolve_scenario_path",
    "set_dotted_key",
    "shipped_scenario_dir",
    "validate_scenario",
    "yaml_problem",
]
