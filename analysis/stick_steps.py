"""A log's rate steps read directly: where the setpoint jumps and holds, the gyro's 10-90 %
rise time, step by step.

The deconvolved step response (``analysis.flight_response``) estimates the loop's answer
to a unit step from whatever the pilot did; when the pilot did give clean steps (a bench's
stick program, a tuning flight's snap rolls) the gyro's own rise after each one is the
direct measurement to hold it against. A step here: the setpoint changes by at least
``min_step`` within ``EDGE_S`` and then stays within 5 % of the change for ``hold_s``;
the rise is between the gyro's first crossings of 10 % and 90 % of the way from the level
before the edge to the level held after it. A step whose stretch of log has a gap (the
logged time jumps by more than ``GAP_S``: the firmware did not run, as a
software-in-the-loop firmware on a loaded host may not, and its bench held the plant) is
no clean reading and is left out.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["EDGE_S", "GAP_S", "step_rise_times"]

EDGE_S = 0.01  # the setpoint's change must happen within this (a stick step, not a sweep)
BEFORE_S = 0.02  # the level before the edge: the setpoint's and gyro's mean over this
GAP_S = 0.03  # a fraction of any rise worth reading; shorter holes are interpolated


def step_rise_times(t_s: np.ndarray, setpoint: np.ndarray, gyro: np.ndarray, *,
                    min_step: float, hold_s: float = 0.15) -> list[float]:
    """The gyro's 10-90 % rise time (s) after each clean setpoint step of the log."""
    t = np.asarray(t_s, float)
    sp = np.asarray(setpoint, float)
    gy = np.asarray(gyro, float)
    if t.size < 3:
        return []
    rate = 1.0 / float(np.median(np.diff(t)))
    edge = max(1, round(EDGE_S * rate))
    hold = round(hold_s * rate)
    before = max(1, round(BEFORE_S * rate))
    out: list[float] = []
    i = before
    while i + edge + hold < t.size:
        jump = sp[i + edge] - sp[i]
        if abs(jump) < min_step:
            i += 1
            continue
        j = i + edge
        size = sp[j] - float(np.mean(sp[i - before:i + 1]))
        plateau = sp[j:j + hold]
        if np.max(np.abs(plateau - sp[j])) > 0.05 * abs(size):
            i = j
            continue
        if np.max(np.diff(t[i - before:j + hold])) > GAP_S:
            i = j + hold
            continue
        start = float(np.mean(gy[i - before:i + 1]))
        z = (gy[i:j + hold] - start) / (float(np.mean(plateau)) - start)
        tt = t[i:j + hold]
        r = _crossing(tt, z, 0.9) - _crossing(tt, z, 0.1)
        if math.isfinite(r):
            out.append(r)
        i = j + hold
    return out


def _crossing(t: np.ndarray, z: np.ndarray, level: float) -> float:
    idx = np.flatnonzero(z >= level)
    if idx.size == 0:
        return math.nan
    k = int(idx[0])
    if k == 0:
        return float(t[0])
    return float(t[k - 1] + (level - z[k - 1]) / (z[k] - z[k - 1]) * (t[k] - t[k - 1]))
