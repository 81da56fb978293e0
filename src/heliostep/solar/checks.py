"""Argument checks and pandas helpers shared by the solar functions (pvlib style: Series in, Series out)."""

from __future__ import annotations

import math
import numbers
import zoneinfo

import numpy as np
import pandas as pd

from heliostep.errors import InputError


def check_finite_scalar(value, name: str, unit: str = "") -> float:
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise InputError(f"{name} must be a real number{unit}, got {value!r}")
    value = float(value)
    if not math.isfinite(value):
        raise InputError(f"{name} must be finite{unit}, got {value!r}")
    return value


def check_range(value, name: str, low: float, high: float, unit: str) -> float:
    value = check_finite_scalar(value, name, f" [{unit}]")
    if not low <= value <= high:
        raise InputError(f"{name} must be within [{low:g}, {high:g}] {unit}, got {value:g}")
    return value


def check_positive(value, name: str, unit: str) -> float:
    value = check_finite_scalar(value, name, f" [{unit}]")
    if value <= 0.0:
        raise InputError(f"{name} must be > 0 {unit}, got {value:g}")
    return value


def check_timezone(timezone: str) -> str:
    if not isinstance(timezone, str) or not timezone:
        raise InputError(f"timezone must be an IANA name such as 'Europe/Rome', got {timezone!r}")
    try:
        zoneinfo.ZoneInfo(timezone)
    except (zoneinfo.ZoneInfoNotFoundError, ValueError) as exc:
        raise InputError(f"timezone {timezone!r} is unknown; use an IANA name such as 'Europe/Rome' or 'UTC'") from exc
    return timezone


def check_times(times) -> pd.DatetimeIndex:
    if isinstance(times, pd.Series):
        times = times.index if isinstance(times.index, pd.DatetimeIndex) else pd.DatetimeIndex(times)
    elif not isinstance(times, pd.DatetimeIndex):
        try:
            times = pd.DatetimeIndex(times)
        except (TypeError, ValueError) as exc:
            raise InputError(f"times must be a timezone-aware pandas DatetimeIndex: {exc}") from exc
    if len(times) == 0:
        raise InputError("times must not be empty (the window holds no sample)")
    if times.tz is None:
        raise InputError(
            "times must be timezone-aware (naive timestamps are ambiguous); "
            "localize them, e.g. times.tz_localize('Europe/Rome')"
        )
    return times


def series_template(*values):
    """The first pandas Series among ``values`` (its index labels the output), or None."""
    for value in values:
        if isinstance(value, pd.Series):
            return value
    return None


def wrap_like(array, template, name=None):
    if template is None:
        return array
    return pd.Series(np.broadcast_to(array, template.shape), index=template.index, name=name)


def as_float_array(value) -> np.ndarray:
    return np.asarray(value, dtype=float)
