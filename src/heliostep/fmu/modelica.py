"""Modelica front end: ``models/*.mo`` → a flat, typed description of one model (pymoca), with errors
that name the file and line and a check for the constructs the export does not support.

Details: docs/fmus.md, ``heliostep.fmu.modelica``.
"""

from __future__ import annotations

import copy
import math
import re
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from heliostep.errors import InputError

if TYPE_CHECKING:  # casadi is imported where a model is translated: a run of built FMUs needs none of it
    import casadi as ca


class ModelicaError(InputError):
    """A model cannot be built: syntax error, unsupported construct, unbalanced model."""


#: Keywords of constructs that the FMU export cannot handle, with the reason given.
UNSUPPORTED = {
    "when": "discrete-time 'when' equations are not supported (no event handling in the export)",
    "reinit": "'reinit' is not supported (no event handling in the export)",
    "pre": "'pre' is not supported (no discrete states in the export)",
    "sample": "'sample' is not supported (no clocked or sampled equations in the export)",
    "algorithm": "'algorithm' sections are not supported; write equations",
    "Integer": "Integer variables are not supported; use Real",
    "Boolean": "Boolean variables are not supported; use Real",
    "discrete": "discrete variables are not supported",
    "delay": "'delay' is not supported",
}

_COMMENT_OR_STRING = re.compile(r'//[^\n]*|/\*.*?\*/|"(?:\\.|[^"\\])*"', re.S)
_WORD = re.compile(r"\b[A-Za-z_]\w*\b")


@dataclass(frozen=True)
class Variable:
    """One scalar of the flat model.

    ``kind`` is one of ``parameter`` (settable), ``calculated_parameter`` (bound to an
    expression of parameters), ``state``, ``derivative``, ``input``, ``algebraic``.
    """

    name: str
    kind: str
    is_output: bool = False
    unit: str = ""
    description: str = ""
    start: float | None = None
    nominal: float | None = None
    min: float | None = None
    max: float | None = None
    state_name: str | None = None  # for a derivative: the state it is the derivative of


@dataclass
class FlatModel:
    """A flattened model as CasADi expressions plus the metadata of its variables."""

    name: str
    description: str
    source_file: Path
    time: ca.MX
    states: list[Variable]
    derivatives: list[Variable]
    inputs: list[Variable]
    parameters: list[Variable]
    calculated_parameters: list[Variable]
    algebraics: list[Variable]
    symbols: dict[str, ca.MX]
    #: residual equations, zero when the model holds
    residual: ca.MX
    #: start value of each state, as expressions of the parameters
    state_start: list[ca.MX]
    #: expression of each calculated parameter in the parameters
    calculated_parameter_values: list[ca.MX] = field(default_factory=list)

    def variables(self) -> list[Variable]:
        return (
            self.parameters
            + self.calculated_parameters
            + self.states
            + self.inputs
            + self.derivatives
            + self.algebraics
        )


def model_files(models_dir: Path) -> list[Path]:
    """The ``.mo`` files of a model folder, sorted by name."""
    files = sorted(Path(models_dir).glob("*.mo"))
    if not files:
        raise ModelicaError(f"{models_dir}: no Modelica (.mo) files found")
    return files


def available_models(models_dir: Path) -> list[str]:
    """Names of the models in a folder: one model per file, named like the file."""
    return [path.stem for path in model_files(models_dir)]


def check_supported(path: Path, text: str) -> None:
    """Raise :class:`ModelicaError` naming file and line at the first unsupported construct."""
    # blank comments and strings but keep their newlines, so line numbers stay right
    code = _COMMENT_OR_STRING.sub(lambda m: re.sub(r"[^\n]", " ", m.group(0)), text)
    for match in _WORD.finditer(code):
        reason = UNSUPPORTED.get(match.group(0))
        if reason:
            line = code.count("\n", 0, match.start()) + 1
            raise ModelicaError(f"{path}:{line}: unsupported construct: {reason}")


def parse_models(models_dir: Path):
    """Parse every ``.mo`` file of ``models_dir`` into one pymoca tree."""
    from pymoca import parser

    tree = None
    for path in model_files(models_dir):
        text = path.read_text(encoding="utf-8")
        try:
            parsed = parser.parse(text)
        except parser.ModelicaSyntaxError as exc:
            reason, location = exc.args[0], exc.args[1] if len(exc.args) > 1 else None
            line = location[1] if location else "?"
            raise ModelicaError(f"{path}:{line}: syntax error: {reason}") from None
        if parsed is None:
            raise ModelicaError(f"{path}: syntax error: the file could not be parsed")
        check_supported(path, text)
        if tree is None:
            tree = parsed
        else:
            tree.extend(parsed)
    return tree


def _number(value) -> float | None:
    """A finite float from a pymoca attribute, or None (unset, NaN or an expression)."""
    import casadi as ca

    if isinstance(value, ca.MX):
        if not value.is_constant():
            return None
        value = float(ca.evalf(value))
    try:
        value = float(value)
    except (TypeError, ValueError):
        return None
    return value if math.isfinite(value) else None


def _descriptions(tree, model_name: str) -> tuple[str, dict[str, str]]:
    from pymoca import tree as pymoca_tree

    flat = pymoca_tree.flatten(copy.deepcopy(tree), model_name)
    (flat_class,) = flat.classes.values()
    comments = {name: symbol.comment or "" for name, symbol in flat_class.symbols.items()}
    return getattr(flat_class, "comment", "") or "", comments


def _translate(models_dir: Path, model_name: str) -> tuple[Path, str, dict[str, str], Any]:
    """pymoca's CasADi model of ``model_name`` with its source file and descriptions (model,
    variables), or :class:`ModelicaError` naming the file."""
    from pymoca.backends.casadi.api import generate_model

    names = available_models(models_dir)
    if model_name not in names:
        raise ModelicaError(f"{models_dir}: no model {model_name!r}; available: {', '.join(names)}")
    source_file = models_dir / f"{model_name}.mo"
    tree = parse_models(models_dir)
    try:
        description, comments = _descriptions(tree, model_name)
        cas = generate_model(copy.deepcopy(tree), model_name, {"cache": False})
    except ModelicaError:
        raise
    except Exception as exc:  # pymoca raises plain exceptions for semantic errors
        raise ModelicaError(f"{source_file}: cannot translate model {model_name}: {exc}") from None

    for attribute in ("delay_states", "string_parameters", "string_constants"):
        if getattr(cas, attribute, None):
            raise ModelicaError(f"{source_file}: unsupported construct: {attribute} in {model_name}")
    return source_file, description, comments, cas


class _VariableFactory:
    """Makes the :class:`Variable` of a pymoca variable and keeps its symbol (``symbols``, in the
    order the variables are made)."""

    def __init__(self, outputs: set[str], comments: dict[str, str]):
        self.outputs, self.comments = outputs, comments
        self.symbols: dict[str, ca.MX] = {}

    def __call__(self, var: Any, kind: str, **extra: Any) -> Variable:
        name = var.symbol.name()
        self.symbols[name] = var.symbol
        unit = getattr(var, "unit", "") or ""
        return Variable(
            name=name,
            kind=kind,
            is_output=name in self.outputs,
            unit=unit,
            description=self.comments.get(name, ""),
            nominal=_number(var.nominal) or None,
            min=_number(var.min),
            max=_number(var.max),
            **extra,
        )


def _constant_substitution(cas: Any) -> Callable[[list[ca.MX]], list[ca.MX]]:
    """A function substituting the model's constants by their values everywhere."""
    import casadi as ca

    constant_symbols = [c.symbol for c in cas.constants]
    constant_values = [ca.MX(_number(c.value) or 0.0) for c in cas.constants]

    def substitute_constants(expressions: list[ca.MX]) -> list[ca.MX]:
        if not constant_symbols or not expressions:
            return expressions
        return ca.substitute(expressions, constant_symbols, constant_values)

    return substitute_constants


def _parameters(
    cas: Any, make: _VariableFactory, source_file: Path, model_name: str
) -> tuple[list[Variable], list[Variable], list[ca.MX]]:
    """(parameters with a value, calculated parameters, their value expressions)."""
    import casadi as ca

    parameters, calculated, calculated_values = [], [], []
    for var in cas.parameters:
        value = _number(var.value)
        if value is not None:
            parameters.append(make(var, "parameter", start=value))
        elif isinstance(var.value, ca.MX):
            calculated.append(make(var, "calculated_parameter"))
            calculated_values.append(var.value)
        else:
            raise ModelicaError(f"{source_file}: parameter {var.symbol.name()} of {model_name} has no value")
    return parameters, calculated, calculated_values


def _resolve_calculated(
    calc_symbols: list[ca.MX], values: list[ca.MX], source_file: Path, model_name: str
) -> list[ca.MX]:
    """The calculated parameters' values with no calculated parameter left in them (they may
    refer to each other: substituted until none is left)."""
    import casadi as ca

    for _ in range(len(values) + 1):
        if not values or not any(ca.depends_on(v, ca.vertcat(*calc_symbols)) for v in values):
            break
        values = ca.substitute(values, calc_symbols, values)
    else:
        raise ModelicaError(f"{source_file}: calculated parameters of {model_name} depend on each other in a cycle")
    return values


def load_model(models_dir: Path, model_name: str) -> FlatModel:
    """Parse, flatten and translate ``model_name`` from the ``.mo`` files of ``models_dir``."""
    import casadi as ca

    source_file, description, comments, cas = _translate(Path(models_dir), model_name)
    make = _VariableFactory(set(cas.outputs), comments)
    substitute_constants = _constant_substitution(cas)
    parameters, calculated, calculated_values = _parameters(cas, make, source_file, model_name)
    states, state_start = [], []
    for var in cas.states:
        start = var.start if isinstance(var.start, ca.MX) else ca.MX(_number(var.start) or 0.0)
        states.append(make(var, "state", start=_number(start)))
        state_start.append(start)
    derivatives = [make(der, "derivative", state_name=state.name) for der, state in zip(cas.der_states, states)]
    inputs = [make(var, "input", start=_number(var.start) or 0.0) for var in cas.inputs]
    algebraics = [make(var, "algebraic") for var in cas.alg_states]
    symbols = make.symbols

    residual = ca.vertcat(*substitute_constants(list(cas.equations)))
    n_unknowns = len(derivatives) + len(algebraics)
    if residual.numel() != n_unknowns:
        raise ModelicaError(
            f"{source_file}: model {model_name} is not balanced: {residual.numel()} equations "
            f"for {n_unknowns} unknowns (derivatives and algebraic variables)"
        )

    calc_symbols = [symbols[v.name] for v in calculated]
    values = _resolve_calculated(calc_symbols, substitute_constants(calculated_values), source_file, model_name)
    if calc_symbols:
        residual = ca.substitute(residual, ca.vertcat(*calc_symbols), ca.vertcat(*values))
        state_start = ca.substitute(state_start, calc_symbols, values)

    return FlatModel(
        name=model_name,
        description=description,
        source_file=source_file,
        time=cas.time,
        states=states,
        derivatives=derivatives,
        inputs=inputs,
        parameters=parameters,
        calculated_parameters=calculated,
        algebraics=algebraics,
        symbols=symbols,
        residual=residual,
        state_start=substitute_constants(list(state_start)),
        calculated_parameter_values=values,
    )
