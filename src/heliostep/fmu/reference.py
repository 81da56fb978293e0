"""How an FMU is named in a scenario: a variant name (a model or a dropped-in FMU) or a path."""

from __future__ import annotations


def is_variant_name(reference: str) -> bool:
    """True for a bare variant name such as ``StepperMotor``; False for a path to an ``.fmu``.

    A path contains a ``/`` (or ``\\``) or ends in ``.fmu`` (any case); everything else names a
    model of the models folder or an FMU dropped into the FMU folder.
    """
    text = str(reference)
    return "/" not in text and "\\" not in text and not text.lower().endswith(".fmu")
