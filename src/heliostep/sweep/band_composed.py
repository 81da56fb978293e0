"""An uncertainty band's samples composed from step families, certified by samples run in full.

Each sample of a band is another drive (its uncertain parameters drawn), so each has a family of its own
(:mod:`heliostep.run.step_family`): it pays where the window holds more than a family costs
(:data:`~heliostep.sweep.certificate.FAMILY_WORTH_S`). :data:`BAND_CERTIFY` samples, drawn by the band's seed,
are co-simulated in full as well and compared figure by figure; a certificate that fails sends every composed
sample to the full co-simulation. Details: docs/running.md, "Uncertainty bands".
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from heliostep.run.step_family import build_family, compose_case, not_composable
from heliostep.scenario import Scenario
from heliostep.sweep.band import BandDesign
from heliostep.sweep.certificate import CERTIFIED_FIGURES, FAMILY_WORTH_S, row_deviation, window_seconds
from heliostep.sweep.worker import summary_figures

__all__ = ["BAND_CERTIFY", "band_ways", "certificate_failures", "composed_sample", "certify_sample"]

#: A band's samples co-simulated both ways to certify the others.
BAND_CERTIFY = 2

#: The table's flat settling columns and the summary's ``settling_time_s`` keys a band names them by.
_SETTLING = {"settling_time_max_s": "max", "settling_time_mean_s": "mean", "settling_not_settled": "not_settled"}


def band_ways(scenario: Scenario, design: BandDesign, exact: bool = False) -> tuple[list[str], str | None]:
    """How each sample of ``design`` runs (``full``, ``composed`` from its family, or ``certificate``: both),
    and why none is composed (None where they are): ``exact``, a scenario whose steps a family cannot give,
    or a window too short for a family to pay."""
    why = "--exact" if exact else not_composable(scenario)
    if why is None and window_seconds(scenario) <= FAMILY_WORTH_S:
        why = f"a window of {window_seconds(scenario) / 3600:.2g} h (a family pays from {FAMILY_WORTH_S / 3600:g} h)"
    if why is not None or design.samples <= BAND_CERTIFY:
        return ["full"] * design.samples, why or "too few samples beside the certificate's"
    ways = ["composed"] * design.samples
    for index in np.random.default_rng(design.seed).choice(design.samples, BAND_CERTIFY, replace=False):
        ways[int(index)] = "certificate"
    return ways, None


def composed_sample(scenario: Scenario) -> tuple[dict | None, str | None]:
    """A sample's figures composed from its own family, as a run's summary names them (None and why where
    it falls back)."""
    composed = compose_case(scenario, build_family(scenario))
    if composed.fallback is not None:
        return None, composed.fallback
    figures = {name: value for name, value in composed.figures.items() if name not in _SETTLING}
    figures["settling_time_s"] = {key: composed.figures[name] for name, key in _SETTLING.items()}
    return figures, None


def certify_sample(summary: Mapping, composed: Mapping) -> dict[str, float]:
    """Each certified figure's deviation of a sample's composition from its full run's ``summary``."""
    full, ours = summary_figures(summary), summary_figures(composed)
    return {name: row_deviation(full, ours, name) for name in CERTIFIED_FIGURES}


def certificate_failures(deviations: Sequence[Mapping[str, float]]) -> list[str]:
    """The certified figures whose deviation exceeds its tolerance on any certificate sample (nan, or none:
    a sample that failed, fails; no sample at all, every figure)."""
    return [
        name
        for name, tolerance in CERTIFIED_FIGURES.items()
        if not deviations or any(not d.get(name, np.nan) <= tolerance for d in deviations)
    ]
