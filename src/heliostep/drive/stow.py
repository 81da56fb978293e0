"""Stow in high wind: when the panel leaves tracking, where it goes, how fast, and when it comes back.

The result is a new panel reference that the sequencer steps like any other, so the moves are
co-simulated step by step.

Details: docs/physics.md, ``heliostep.drive.stow``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.optimize import brentq

__all__ = ["StowMove", "StowPlan", "plan_stow", "stowed_spans", "threshold_crossings"]

#: Longest spacing of the reference's points along a slew ramp [s] (a ramp is linear between them).
RAMP_SPACING = 0.05


@dataclass(frozen=True)
class StowMove:
    """One slew of the panel: ``kind`` "stow" or "return", from ``start`` to ``end`` [s from the
    window start], from ``from_angle`` to ``to_angle`` [rad]."""

    kind: str
    start: float
    end: float
    from_angle: float
    to_angle: float

    def record(self) -> dict:
        """As kept in the run's metadata (``drive.stow_moves``), angles in [deg]."""
        return {
            "kind": self.kind,
            "start_s": float(self.start),
            "end_s": float(self.end),
            "from_angle_deg": float(np.degrees(self.from_angle)),
            "to_angle_deg": float(np.degrees(self.to_angle)),
        }


@dataclass(frozen=True)
class StowPlan:
    """The panel reference with stow (``times`` [s], ``panel_angle`` [rad]), its moves, and the
    spans off tracking (``stowed``: (start of the stow move, end of the return move or the window's end))."""

    times: np.ndarray
    panel_angle: np.ndarray
    moves: tuple[StowMove, ...]
    stowed: tuple[tuple[float, float], ...]


def threshold_crossings(times, speed, threshold: float) -> tuple[np.ndarray, np.ndarray]:
    """Where a piecewise-linear speed goes above ``threshold`` (up) and back to it or below (down) [s].

    Returns
    -------
    up, down : numpy.ndarray
        Sorted instants; a speed above the threshold at ``times[0]`` goes up at ``times[0]``.
    """
    t, v = np.asarray(times, dtype=float), np.asarray(speed, dtype=float)
    above = v > threshold
    up: list[float] = [float(t[0])] if above[0] else []
    down: list[float] = []
    for k in np.nonzero(above[1:] != above[:-1])[0]:
        fraction = (threshold - v[k]) / (v[k + 1] - v[k])  # linear between the knots
        (up if above[k + 1] else down).append(float(t[k] + fraction * (t[k + 1] - t[k])))
    return np.array(up), np.array(down)


def stowed_spans(times, speed, threshold: float, calm_time: float, end: float) -> list[tuple[float, float]]:
    """(stow, return) instants [s]: stow when the speed goes above ``threshold``, return once it has
    stayed at or below it for ``calm_time`` [s] (``end`` when that is not before the window's end)."""
    up, down = threshold_crossings(times, speed, threshold)
    spans: list[tuple[float, float]] = []
    k = 0
    while k < len(up):
        start = float(up[k])
        later_down = down[down > start]
        back = end
        while len(later_down):
            calm_from = float(later_down[0])
            next_up = up[up > calm_from]
            if not len(next_up) or next_up[0] > calm_from + calm_time:
                back = min(end, calm_from + calm_time)
                break
            later_down = down[down > next_up[0]]
        spans.append((start, back))
        k = int(np.searchsorted(up, back, side="right"))
        if back >= end:
            break
    return spans


def _ramp(start: float, angle: float, target: float, rate: float) -> float:
    """End [s] of a slew from ``angle`` to ``target`` [rad] at ``rate`` [rad/s] from ``start``."""
    return start + abs(target - angle) / rate


def _return_end(tracking: Callable, start: float, stow_angle: float, rate: float, end: float) -> float:
    """When a slew from ``stow_angle`` at ``start`` meets the tracking reference (``end`` if not before it)."""
    direction = np.sign(float(tracking(start)) - stow_angle)
    if direction == 0.0:
        return start

    def gap(t: float) -> float:
        return float(direction * (tracking(t) - stow_angle - direction * rate * (t - start)))

    if gap(end) > 0.0:
        return end
    return float(brentq(gap, start, end, xtol=1e-9))


def plan_stow(times, tracking: Callable, spans, stow_angle: float, slew_rate: float, end: float) -> StowPlan:
    """The panel reference with the stowed ``spans`` (:func:`stowed_spans`).

    Parameters
    ----------
    times : array  [s]
        The tracking reference's grid (kept where tracking).
    tracking : callable
        The tracking reference panel angle [rad] at times [s].
    spans : sequence of (float, float)  [s]
    stow_angle : float  [rad]
    slew_rate : float  [rad/s]
        The panel's slew rate, > 0.
    end : float  [s]
        The window's end.
    """
    grid = np.asarray(times, dtype=float)
    pieces, moves, stowed = [], [], []
    cursor = 0.0
    for stow_at, back_at in spans:
        if stow_at < cursor:
            continue
        keep = grid[(grid >= cursor) & (grid < stow_at)]
        pieces.append((keep, np.asarray(tracking(keep), dtype=float)))
        angle = float(tracking(stow_at))
        reached = min(end, _ramp(stow_at, angle, stow_angle, slew_rate))
        moves.append(StowMove("stow", stow_at, reached, angle, stow_angle))
        pieces.append(
            _linear(stow_at, angle, reached, angle + np.sign(stow_angle - angle) * slew_rate * (reached - stow_at))
        )
        leave = max(back_at, reached)
        if leave >= end:
            pieces.append((np.array([end]), np.array([stow_angle if reached < end else pieces[-1][1][-1]])))
            stowed.append((stow_at, end))
            cursor = end
            break
        met = _return_end(tracking, leave, stow_angle, slew_rate, end)
        met_angle = (
            float(tracking(met))
            if met < end
            else stow_angle + np.sign(float(tracking(leave)) - stow_angle) * slew_rate * (end - leave)
        )
        pieces.append(_linear(leave, stow_angle, met, met_angle))
        moves.append(StowMove("return", leave, met, stow_angle, met_angle))
        stowed.append((stow_at, met))
        cursor = met
    if cursor < end:
        keep = grid[grid >= cursor]
        keep = np.concatenate([[cursor], keep[keep > cursor]]) if cursor > 0.0 else keep
        pieces.append((keep, np.asarray(tracking(keep), dtype=float)))
    t = np.concatenate([p[0] for p in pieces])
    a = np.concatenate([p[1] for p in pieces])
    t, first = np.unique(t, return_index=True)
    return StowPlan(t, a[first], tuple(moves), tuple(stowed))


def _linear(t0: float, a0: float, t1: float, a1: float) -> tuple[np.ndarray, np.ndarray]:
    """Points of a straight ramp from (t0, a0) to (t1, a1), at most :data:`RAMP_SPACING` apart."""
    n = max(2, int(np.ceil((t1 - t0) / RAMP_SPACING)) + 1)
    t = np.linspace(t0, t1, n)
    return t, a0 + (a1 - a0) * (t - t0) / (t1 - t0) if t1 > t0 else np.full(n, a0)
