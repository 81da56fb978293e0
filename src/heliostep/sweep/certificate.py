"""A sweep's certificate: the figures composed cases carry, how far from the full co-simulation each may be.

Details: docs/sweep.md, ``heliostep.sweep.composed``.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

#: Cases of a sweep co-simulated in full to certify its composed ones, at the least.
CERTIFICATE_CASES = 20
#: The figures a step family composes, each with the largest deviation from the full co-simulation a
#: certificate accepts: relative, and 0 for the step counts (exact). The light's is relative to the light
#: ideal tracking puts on the tube (``light_energy_ideal_J``), not to its own: a mirror whose rays miss
#: the tube gets next to none, of which any difference is a large share. The settling times' are the full
#: co-simulation's own resolution: where a swing of a step's ring peaks at the settling band, the solver's
#: tolerance decides whether it leaves the band, and the step's settling time moves by half the ring's period
#: (docs/sweep.md, "Settling").
CERTIFIED_FIGURES = {
    "peak_torque_Nm": 5e-3,
    "peak_phase_current_A": 5e-3,
    "electrical_energy_J": 1e-3,
    "max_tracking_error_deg": 1e-2,
    "settling_time_max_s": 1e-1,
    "settling_time_mean_s": 2e-2,
    "settling_not_settled": 0.0,
    "light_energy_J": 1e-3,
    "light_energy_ideal_J": 1e-3,
    "missed_steps": 0.0,
    "steps_lost": 0.0,
}


#: The figure whose deviation is relative to another of the full run's figures.
RELATIVE_TO = {"light_energy_J": "light_energy_ideal_J"}


def deviation(full: float | None, composed: float | None, name: str, scale: float | None = None) -> float:
    """How far a composed figure ``name`` is from the full co-simulation's: relative (to ``scale`` where
    given, else to the full figure), or the difference of a step count (nan where either is missing)."""
    if full is None or composed is None or not np.isfinite(full):
        return float("nan")
    if CERTIFIED_FIGURES[name] == 0.0:
        return float(abs(composed - full))
    scale = abs(full) if scale is None else abs(scale)
    return float(abs(composed - full) / scale) if scale else float(abs(composed - full))


def row_deviation(full: Mapping, composed: Mapping, name: str) -> float:
    """:func:`deviation` of figure ``name`` between a full run's row and a composed one."""
    scale = full.get(RELATIVE_TO[name]) if name in RELATIVE_TO else None
    return deviation(full.get(name), composed.get(name), name, scale)


def certified_row(full: Mapping, composed: Mapping | None, figures: Sequence[str] = tuple(CERTIFIED_FIGURES)) -> dict:
    """A certificate case's full row with the deviation of the composed one of each certified figure (of
    ``figures``: those the caller keeps)."""
    row = {**full, "method": "certificate"}
    for name in figures:
        row[f"deviation_{name}"] = float("nan") if composed is None else row_deviation(full, composed, name)
    return row


def failed_figures(rows: Sequence[Mapping], figures: Sequence[str] = tuple(CERTIFIED_FIGURES)) -> list[str]:
    """The certified figures (of ``figures``) whose largest deviation over a family's certificate ``rows``
    exceeds its tolerance (a certificate case that failed certifies nothing: its figures fail)."""
    failed = []
    for name in figures:
        tolerance = CERTIFIED_FIGURES[name]
        values = [row.get(f"deviation_{name}") for row in rows]
        if not values or any(v is None or not np.isfinite(v) or v > tolerance for v in values):
            failed.append(name)
    return failed


#: A family is built when the cases it would compose hold more window than this [s]: a family costs about as
#: much CPU as 3.4 hours of a day's co-simulation (benchmarks/bench_sweep.py --full-day), so fewer would be
#: composed at a loss.
FAMILY_WORTH_S = 4 * 3600.0


def certificate_sample(groups: Mapping[str, Sequence[float]], certify: int = CERTIFICATE_CASES, seed: int = 0) -> dict:
    """Per group (key -> its cases' window durations [s], in sweep order) the positions of its certificate's
    cases: its share of ``certify``, at least two, one at random in each of as many equal runs of its cases
    (so spread over the sweep), drawn by ``seed``; None for a group whose other cases hold no more than
    :data:`FAMILY_WORTH_S` of window (it runs in full)."""
    total = sum(len(durations) for durations in groups.values())
    random = np.random.default_rng(seed)
    sample: dict = {}
    for key, durations in groups.items():
        count = max(2, int(np.ceil(certify * len(durations) / total)))
        if len(durations) <= count:
            sample[key] = None
            continue
        picked = [int(random.choice(run)) for run in np.array_split(np.arange(len(durations)), count)]
        composed = sum(durations) - sum(durations[k] for k in picked)
        sample[key] = picked if composed > FAMILY_WORTH_S else None
    return sample


def window_seconds(scenario) -> float:
    """A case's window [s] (:meth:`heliostep.scenario.Scenario.window_bounds`)."""
    start, end = scenario.window_bounds()
    return (end - start).total_seconds()
