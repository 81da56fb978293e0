"""What a run's light figures mean, and which are not meaningful (``light_notes`` in ``summary.json``).

:func:`light_notes` of :func:`heliostep.results.light.on_tube.light_figures`' figures: the stepping's change on a
driven secondary (not a loss; its first-order terms), the shared primary's exact zeros, one mirror
without neighbours, and the figures below the sun grid's interpolation noise.
"""

from __future__ import annotations

from collections.abc import Mapping

__all__ = ["INTERPOLATION_NOISE", "light_notes"]

#: Relative size of the rows' interpolation error in an energy: linear interpolation of the sun and
#: the ideal angles on the SUN_GRID_S grid errs by at most (omega dt)^2 / 8 = 7e-8 rad (omega =
#: 7.27e-5 rad/s, the Earth's rotation), the cosine by that relative to it times tan(theta_i) <~ 1;
#: a figure comparing interpolated with exact angles below 1e-6 of the energy (a factor 10) is noise.
INTERPOLATION_NOISE = 1e-6


def _sign(cosine_term: float, mean_error: float | None) -> str:
    """The sign of the cosine's mean slope, from its first-order term and the mean error."""
    if not mean_error or not cosine_term:
        return "0"
    return "+" if cosine_term / mean_error > 0 else "-"


def _stepping_note(figures: Mapping) -> str:
    """What a secondary's ``light_stepping_change_J`` means, with its first-order terms where computed."""
    change, first = figures["light_stepping_change_J"], figures["light_stepping_first_order_J"]
    if first is None:
        return (
            f"light_stepping_change_J = {change:.3g} J (actual - reference) is not a"
            " loss: the secondary's stepping error moves the image along the tube; its first-order terms were not"
            " computed (light_first_order off)"
        )
    cosine, mean = figures["light_stepping_first_order_cosine_J"], figures["light_stepping_mean_error_rad"]
    mean_text = "none: no light" if mean is None else f"{mean:.3g} rad"
    return (
        f"light_stepping_change_J = {change:.3g} J (actual - reference; light_lost_stepping_J is its negative)"
        " is not a loss: the secondary's stepping error moves the image along the tube (no cost where the"
        " tube runs on past it) and changes the light to first order,"
        f" light_stepping_first_order_J = {first:.3g} J,"
        f" of which the cosine's {cosine:.3g} J (the rest the intercept's, where the image is off the tube's"
        f" axis); its sign is that of the power-weighted mean error ({mean_text}) times that of the"
        f" cosine's slope d cos / d theta ({_sign(cosine, mean)}), the reference (the secondary's own two-axis"
        " law, each image aimed at its own cross-section) being no optimum"
    )


def light_notes(figures: Mapping, axis: str, distance: float) -> list[str]:
    """What the light figures mean, and which are not meaningful (``light_notes`` in summary.json)."""
    notes = []
    reference = figures["light_energy_reference_J"]
    if "light_stepping_change_J" in figures and axis == "secondary":
        notes.append(_stepping_note(figures))
    if distance == 0.0 and axis == "secondary":
        notes.append("light_lost_shared_primary_J is exactly 0: the central mirror's primary is the shared one")
    if axis == "primary":
        notes.append("light_lost_shared_primary_J is 0: a driven primary shares nothing")
    notes.append(
        "one mirror: the receiver's own shadow on it is counted; shading and blocking by neighbouring mirrors"
        " are not (heliostep field-light and heliostep end-loss have them)"
    )
    law = figures["light_lost_reference_law_J"]
    if reference > 0 and abs(law) < INTERPOLATION_NOISE * reference:
        notes.append(
            f"light_lost_reference_law_J = {law:.3g} J is below the sun grid's interpolation noise"
            f" ({INTERPOLATION_NOISE:g} of the energy): not meaningful"
        )
    return notes
