"""``modelDescription.xml``'s ModelStructure checked against its variables before heliostep uses it.

ModelStructure names variables by their index in ModelVariables (FMI 2.0) or by value reference
(FMI 3.0). When the variables change under it (variables inserted before the others, one declared
twice) the indices point at the wrong variables: a derivative that is not one, an output that is not
an output. :func:`check_model_structure` refuses such a description naming the file and the entry.
"""

from __future__ import annotations

from collections import Counter
from pathlib import Path

from heliostep.errors import InputError

__all__ = ["check_model_structure"]


def _refuse_duplicates(path: Path, variables) -> None:
    twice = sorted(name for name, count in Counter(v.name for v in variables).items() if count > 1)
    if twice:
        shown = ", ".join(map(repr, twice[:5])) + (f" and {len(twice) - 5} more" if len(twice) > 5 else "")
        raise InputError(f"{path}: modelDescription.xml declares the variable(s) {shown} twice; expected unique names")


def _refuse_derivatives(path: Path, derivatives) -> None:
    for unknown in derivatives:
        if getattr(unknown.variable, "derivative", None) is None:
            raise InputError(
                f"{path}: modelDescription.xml: ModelStructure/Derivatives names {unknown.variable.name!r}, which is "
                "not the derivative of a state (no derivative attribute); expected its indices to match ModelVariables"
            )


def _refuse_outputs(path: Path, outputs) -> None:
    for unknown in outputs:
        if unknown.variable.causality != "output":
            raise InputError(
                f"{path}: modelDescription.xml: ModelStructure/Outputs names {unknown.variable.name!r} of causality "
                f"{unknown.variable.causality!r}; expected its indices to match ModelVariables' outputs"
            )


def check_model_structure(path: Path, description) -> None:
    """Refuse a description (fmpy's ``ModelDescription``) whose variables are declared twice or whose
    ModelStructure names variables that are not derivatives or outputs where it lists them."""
    variables = list(description.modelVariables)
    _refuse_duplicates(path, variables)
    _refuse_derivatives(path, description.derivatives)
    _refuse_outputs(path, description.outputs)
