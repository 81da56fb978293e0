"""Units scaled to the signal drawn: the SI prefix that puts a series' largest magnitude in [1, 1000)."""

from __future__ import annotations

import math

import numpy as np

__all__ = ["PREFIXES", "si_scale"]

#: SI prefixes by power of 1000.
PREFIXES = {-4: "p", -3: "n", -2: "µ", -1: "m", 0: "", 1: "k", 2: "M", 3: "G"}


def si_scale(*series, unit: str) -> tuple[float, str]:
    """The factor to multiply ``series`` by and the unit to label it with (e.g. ``(1.0, "W")`` for 45 W,
    ``(1e3, "mW")`` for 0.02 W, ``(1e-3, "kW")`` for 2 kW): the SI prefix putting the largest finite
    magnitude in [1, 1000) (no prefix for zeros or no value).

    Parameters
    ----------
    *series : array-like
        The values drawn [unit].
    unit : str
        Their unit.

    Returns
    -------
    tuple of (float, str)
        The factor [-] and the prefixed unit.
    """
    finite = [np.abs(np.asarray(s, dtype=float)) for s in series]
    largest = max((float(np.nanmax(np.where(np.isfinite(s), s, np.nan))) for s in finite if np.isfinite(s).any()),
                  default=0.0)  # fmt: skip
    if not largest > 0.0:
        return 1.0, unit
    power = min(max(math.floor(math.log10(largest) / 3.0), min(PREFIXES)), max(PREFIXES))
    return 1000.0 ** (-power), PREFIXES[power] + unit
