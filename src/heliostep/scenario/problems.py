"""Turning pydantic's validation errors into one line per problem: file, dotted key, what was expected."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any, get_args

from pydantic import BaseModel, ValidationError

from heliostep.scenario.keys import KeyProblems, dotted


def _model_of(annotation) -> type[BaseModel] | None:
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return annotation
    for argument in get_args(annotation):
        model = _model_of(argument)
        if model is not None:
            return model
    return None


def _field_at(root: type[BaseModel], loc: Sequence):
    """(model holding the last key, its FieldInfo) for a key path, as far as models reach."""
    model: type[BaseModel] | None = root
    info = None
    for depth, part in enumerate(loc):
        if model is None or part not in model.model_fields:
            return (model if depth == len(loc) - 1 else None), None
        info = model.model_fields[part]
        if depth < len(loc) - 1:
            model = _model_of(info.annotation)
    return model, info


def _explain(root: type[BaseModel], error: Mapping[str, Any]) -> list[tuple[tuple, str]]:
    """(key path, message) lines for one pydantic error."""
    loc, kind = tuple(error["loc"]), error["type"]
    cause = (error.get("ctx") or {}).get("error")
    if isinstance(cause, KeyProblems):
        return [(loc + path, message) for path, message in cause.problems]
    if cause is not None:
        return [(loc, str(cause))]
    model, info = _field_at(root, loc)
    meaning = f" ({info.description})" if info is not None and info.description else ""
    if kind == "extra_forbidden":
        allowed = f"; allowed keys: {', '.join(model.model_fields)}" if model is not None else ""
        return [(loc, f"unknown key{allowed}")]
    if kind == "missing":
        return [(loc, f"required key is missing{meaning}")]
    if kind == "literal_error":
        return [(loc, f"expected one of {error['ctx']['expected']}, got {error['input']!r}")]
    return [(loc, f"{error['msg']}{meaning}, got {error['input']!r}")]


#: Tags pydantic appends to the key path of each member of a scalar union (a parameter value).
_UNION_TAGS = ("bool", "int", "float", "str")


def format_validation_error(exc: ValidationError, source: str, root: type[BaseModel]) -> str:
    lines, unions = [], set()
    for error in exc.errors(include_url=False):
        loc = tuple(error["loc"])
        if loc and loc[-1] in _UNION_TAGS:  # one line for a value that is none of the union's types
            if loc[:-1] not in unions:
                unions.add(loc[:-1])
                lines.append(
                    f"{source}: {dotted(loc[:-1])}: expected a number, true/false or a string, got {error['input']!r}"
                )
            continue
        for loc, message in _explain(root, error):
            lines.append(f"{source}: {dotted(loc) or '(top level)'}: {message}")
    return "\n".join(lines)
