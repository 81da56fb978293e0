"""Loading a scenario: read the YAML, apply ``--set`` overrides, validate; shipped scenarios by name."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path

from pydantic import ValidationError

from heliostep.errors import InputError
from heliostep.paths import fmus_dir, scenarios_dir
from heliostep.scenario.keys import apply_overrides
from heliostep.scenario.model import DEFAULT_FMUS, Scenario
from heliostep.scenario.problems import format_validation_error
from heliostep.scenario.yaml_io import read_yaml_file


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
        raise InputError(
            f"{source}: the top level must be a mapping of keys (name, site, window, ...), got {type(data).__name__}"
        )
    folder = Path.cwd() if folder is None else Path(folder).absolute()
    data = _with_ssp_system(dict(data), source, folder)
    try:
        scenario = Scenario.model_validate(data)
    except ValidationError as exc:
        raise InputError(format_validation_error(exc, source, Scenario)) from None
    scenario._folder = folder
    scenario._source = source
    return scenario


def _with_ssp_system(data: dict, source: str, folder: Path) -> dict:
    """``system: FILE.ssp`` (relative to the scenario's folder): its components become ``fmus`` (the
    default instances dropped), its connections ``connections`` (their transformations
    ``transformations``) unless the scenario gives them, its parameter bindings ``parameters`` under
    the scenario's own (which win)."""
    reference = data.get("system")
    if reference is None:
        return data
    if not isinstance(reference, str) or not reference.lower().endswith(".ssp"):
        raise InputError(f"{source}: system: expected the path of an .ssp file, got {reference!r}")
    path = Path(reference) if Path(reference).is_absolute() else folder / reference
    from heliostep.fmu.ssp import read_ssp  # (here: its XML writer imports urllib, http, ssl and email)

    try:
        system = read_ssp(path, fmus_dir())
    except InputError as exc:
        raise InputError(f"{source}: system: {exc}") from None
    given = data.get("fmus") or {}
    data["fmus"] = {**dict.fromkeys(DEFAULT_FMUS), **{k: str(v) for k, v in system.fmus.items()}, **given}
    if data.get("connections") is None:
        data["connections"] = [list(pair) for pair in system.connections]
        transforms = {target: {"factor": f, "offset": o} for target, (f, o) in system.transformations.items()}
        data["transformations"] = {**transforms, **(data.get("transformations") or {})}
    parameters = {instance: dict(values) for instance, values in system.parameters.items()}
    for instance, values in (data.get("parameters") or {}).items():
        parameters.setdefault(instance, {}).update(values or {})
    data["parameters"] = parameters
    return data


def shipped_scenario_dir() -> Path:
    """The folder of the scenarios shipped with heliostep."""
    return scenarios_dir()


def resolve_scenario_path(path: str | Path) -> Path:
    """``path`` if it exists, else the shipped scenario of that name.

    ``jan21-central``, ``jan21-central.yaml`` and ``scenarios/jan21-central.yaml`` (from any
    directory) name the shipped ``jan21-central.yaml``. A path that is neither is an :class:`InputError`
    naming it and, for a name, the close names of the shipped scenarios (``jan21-centrl``: ``jan21-central``).
    """
    path = Path(path)
    name = _shipped_name(path)
    if path.exists() or path.is_symlink():  # (a dangling link: its reader says so)
        return path
    shipped = shipped_scenario_dir() / f"{name}.yaml"
    if name is not None and shipped.is_file():
        return shipped
    raise _missing_scenario(path, name)


def _shipped_name(path: Path) -> str | None:
    """The shipped scenario's name ``path`` would be (a bare name, with or without ``.yaml``, or one under a
    ``scenarios`` folder), or None for a path elsewhere."""
    if path.parent != Path(".") and path.parent.name != "scenarios":
        return None
    return path.stem if path.suffix in (".yaml", ".yml") else path.name


def shipped_scenarios() -> dict[str, str]:
    """The shipped scenarios, name (the file's, which ``run`` takes) -> description (on one line; "" without):
    the shipped folder's ``*.yaml`` files that hold a ``name`` (not the tolerances of ``heliostep regress``)."""
    shipped = {}
    for path in sorted(shipped_scenario_dir().glob("*.yaml")):
        data = read_yaml_file(path, "scenario")
        if isinstance(data, Mapping) and "name" in data:
            shipped[path.stem] = " ".join(str(data.get("description") or "").split())
    return shipped


def _missing_scenario(path: Path, name: str | None) -> InputError:
    """A scenario file that is not there; for a ``name`` that could be a shipped scenario's, the close ones."""
    error = f"{path}: scenario file not found"
    if name is None:
        return InputError(error)
    from heliostep.scenario.catalogue import close_names

    near = close_names(name, list(shipped_scenarios()), cutoff=0.75)
    hint = f" (close: {', '.join(near)})" if near else ""
    return InputError(f"{error}, nor a shipped scenario {name!r}{hint}; `heliostep scenarios` lists them")


def load_scenario(path, overrides: Sequence[str] = ()) -> Scenario:
    """Read, override and validate a scenario file.

    Parameters
    ----------
    path : str or Path
        YAML scenario file, or the name of a shipped scenario (see :func:`resolve_scenario_path`).
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
        Missing (a name: with the shipped scenarios' close names) or unreadable file, invalid YAML (with
        its line), a top level that is not a mapping, a malformed override, or an invalid scenario (one
        line per problem, each naming the file, the key path and what was expected).
    """
    if isinstance(overrides, str):
        raise TypeError("overrides must be a sequence of 'dotted.key=value' strings, not one string")
    path = resolve_scenario_path(path)
    source = str(path)
    data = read_yaml_file(path, "scenario")
    if not isinstance(data, dict):
        what = "empty" if data is None else f"a {type(data).__name__}"
        raise InputError(
            f"{source}: the top level must be a mapping of keys (name, site, window, ...), the file holds {what}"
        )
    data = apply_overrides(data, overrides, source)
    return validate_scenario(data, source=source, folder=path.absolute().parent)
