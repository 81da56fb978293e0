"""Scenario files: the typed, validated description of one run.

:func:`load_scenario` reads a YAML mapping, applies ``--set`` overrides and validates it into a
:class:`Scenario` (pydantic v2); unknown keys are errors, and every problem is an
:class:`~heliostep.errors.InputError` naming the file and the dotted key.

Details: docs/running.md, ``heliostep.scenario``.
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
