"""A log's rate steps read directly: where the setpoint jumps and holds, the gyro's 10-90 %
rise time, step by step.

The deconvolved step response (``analysis.flight_response``) estimates the loop's answer
to a unit step from whatever the pilot did; when the pilot did give clean steps (a bench's
stick program, a tuning flight's snap rolls) the gyro's own rise after each one is the
direct measurement to hold it against. A step here: the setpoint changes by at least
``min_step`` within ``EDGE_S`` (its edge: the last sample before the setpoint leaves its
level; a gyro still swinging from the step before must not be read as this one's rise,
which the look-ahead's start, up to ``EDGE_S`` early, did: a return to zero after a 0.25 s
hold with 50 % overshoot read 68-75 ms against the 47-53 ms its edge gives) and,
``SETTLE_S`` later (a firmware's RC smoothing rounds a
stick step off over some 30 ms), stays within 5 % of the change for ``hold_s``;
the rise is between the gyro's first crossings of 10 % and 90 % of the way from the level
before the edge to the level held after it. A step whose stretch of log has a gap (the
logged time jumps by more than ``GAP_S``: the firmware did not run, as a
software-in-the-loop firmware on a loaded host may not, and its bench held the plant) is
no clean reading and is left out.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["EDGE_S", "GAP_S", "step_readings", "step_rise_times", "unit_step_figures"]

EDGE_S = 0.02  # the setpoint must change by min_step within this (a stick step, not a sweep)
BEFORE_S = 0.02  # the level before the edge: the setpoint's and gyro's mean over this
SETTLE_S = 0.04  # from the edge to where the setpoint must hold (RC smoothing's tail)
GAP_S = 0.03  # a fraction of any rise worth reading; shorter holes are interpolated
EDGE_LEAVE = 0.02  # the setpoint has left its level once it moved this share of the step


def step_rise_times(t_s: np.ndarray, setpoint: np.ndarray, gyro: np.ndarray, *,
                    min_step: float, hold_s: float = 0.15) -> list[float]:
    """The gyro's 10-90 % rise time (s) after each clean setpoint step of the log."""
    return [r for r, _ in step_readings(t_s, setpoint, gyro, min_step=min_step,
                                        hold_s=hold_s)]


def unit_step_figures(t_s: np.ndarray, z: np.ndarray) -> tuple[float, float]:
    """A response normalised to its step (0 before, 1 asked): the 10-90 % rise (s, first
    crossings; NaN if never reached) and the overshoot over the asked level (%)."""
    rise = _crossing(t_s, z, 0.9) - _crossing(t_s, z, 0.1)
    return rise, max(0.0, float(np.max(z)) - 1.0) * 100.0


def step_readings(t_s: np.ndarray, setpoint: np.ndarray, gyro: np.ndarray, *,
                  min_step: float, hold_s: float = 0.15) -> list[tuple[float, float]]:
    """Each clean setpoint step's gyro rise (s) and overshoot over the held setpoint (%)."""
    t = np.asarray(t_s, float)
    sp = np.asarray(setpoint, float)
    gy = np.asarray(gyro, float)
    if t.size < 3:
        return []
    # spans in time, not samples: a log's rows need not be evenly spaced (a blackbox
    # drops frames; the rate a median spacing gives would stretch a span past the step)
    edge = np.searchsorted(t, t + EDGE_S)
    out: list[tuple[float, float]] = []
    i = int(np.searchsorted(t, t[0] + BEFORE_S))
    while i < t.size:
        e = int(edge[i])
        j = int(np.searchsorted(t, t[i] + EDGE_S + SETTLE_S))
        end = int(np.searchsorted(t, t[i] + EDGE_S + SETTLE_S + hold_s))
        if end >= t.size:
            break
        if e >= t.size or abs(sp[e] - sp[i]) < min_step or end - j < 3:
            i += 1
            continue
        plateau = sp[j:end]
        level = float(np.mean(plateau))
        # the edge: the last sample before the setpoint leaves its level (up to EDGE_S
        # after i), so the gyro's level before is read before the step, not in its rise
        away = np.abs(sp[i:e + 1] - sp[i]) > EDGE_LEAVE * abs(level - sp[i])
        i += max(int(np.argmax(away)) - 1, 0)
        b = int(np.searchsorted(t, t[i] - BEFORE_S))
        size = level - float(np.mean(sp[b:i + 1]))
        if np.max(np.abs(plateau - level)) > 0.05 * abs(size):
            i = e
            continue
        if np.max(np.diff(t[b:end])) > GAP_S:
            i = end
            continue
        start = float(np.mean(gy[b:i + 1]))
        r, over = unit_step_figures(t[i:end], (gy[i:end] - start) / (level - start))
        if math.isfinite(r):
            out.append((r, over))
        i = end
    return out


def _crossing(t: np.ndarray, z: np.ndarray, level: float) -> float:
    idx = np.flatnonzero(z >= level)
    if idx.size == 0:
        return math.nan
    k = int(idx[0])
    if k == 0:
        return float(t[0])
    return float(t[k - 1] + (level - z[k - 1]) / (z[k] - z[k - 1]) * (t[k] - t[k - 1]))
