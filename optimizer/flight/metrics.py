"""Step-response figures of a flown maneuver: rise, overshoot, settling, saturation."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

RISE_LOW, RISE_HIGH = 0.1, 0.9  # 10-90 % rise time
SETTLE_BAND = 0.02  # 2 % settling band


def _first_crossing(t: np.ndarray, z: np.ndarray, level: float) -> float:
    """First time the normalised response z reaches ``level`` (linear interpolation)."""
    idx = np.flatnonzero(z >= level)
    if idx.size == 0:
        return math.nan
    i = int(idx[0])
    if i == 0:
        return float(t[0])
    z0, z1 = z[i - 1], z[i]
    return float(t[i - 1] + (level - z0) / (z1 - z0) * (t[i] - t[i - 1]))


def step_metrics(t: np.ndarray, y: np.ndarray, t_step: float, start: float,
                 target: float) -> dict[str, float | None]:
    """Rise time (10-90 %), overshoot and settling time (2 % band) of y after ``t_step``.

    Times in ms from the step command; overshoot and the error at the end in % of the
    step size (settling is None when the response is outside the band at the end, e.g.
    a limit cycle of the ESC's command quantisation).
    """
    after = t >= t_step
    tt, yy = t[after] - t_step, y[after]
    size = target - start
    z = (yy - start) / size
    rise = _first_crossing(tt, z, RISE_HIGH) - _first_crossing(tt, z, RISE_LOW)
    overshoot = max(0.0, float(np.max(z)) - 1.0) * 100.0
    outside = np.flatnonzero(np.abs(z - 1.0) > SETTLE_BAND)
    if outside.size == 0:
        settle = 0.0
    elif outside[-1] == z.size - 1:
        settle = math.nan  # never settled within the maneuver
    else:
        settle = float(tt[outside[-1] + 1])
    return {
        "rise_time_ms": _ms(rise),
        "overshoot_pct": overshoot,
        "settling_time_ms": _ms(settle),
        "final_error_pct": abs(float(z[-1]) - 1.0) * 100.0,
    }


def disturbance_metrics(t: np.ndarray, y: np.ndarray, t_start: float,
                        band: float) -> dict[str, float | None]:
    """Peak deviation of y from 0 after ``t_start`` and the time it stays within ``band``."""
    after = t >= t_start
    tt, yy = t[after] - t_start, np.abs(y[after])
    outside = np.flatnonzero(yy > band)
    if outside.size == 0:
        settle = 0.0
    elif outside[-1] == yy.size - 1:
        settle = math.nan
    else:
        settle = float(tt[outside[-1] + 1])
    return {"peak": float(np.max(yy)), "settling_time_ms": _ms(settle)}


def _ms(x: float) -> float | None:
    return None if not math.isfinite(x) else x * 1e3


def summary(values: dict[str, Any]) -> dict[str, Any]:
    """JSON-ready copy: floats rounded to 0.01 (ms and %), NaN as None."""
    out: dict[str, Any] = {}
    for k, v in values.items():
        if isinstance(v, float):
            out[k] = round(v, 4) if math.isfinite(v) else None
        else:
            out[k] = v
    return out
