"""Rest detection and gyro bias estimated at rest, causal and vectorised.

Paper B removes a gyro bias measured at rest before flight. Here the bias is re-estimated
whenever the sensor rests, as VQF does (Laidig & Seel, Information Fusion 91, 2023,
section "rest detection"): the sensor is at rest when, for at least ``min_rest_s``, the
gyro deviates from its low-passed value by less than ``gyro_dev_rad_s``, its low-passed
value stays below ``gyro_max_rad_s`` (slow real turning is not bias) and the accelerometer
deviates from its low-passed value by less than ``acc_dev_m_s2``. During rest the bias is
a first-order low-pass of the gyro; in motion it is held. Everything uses only past
samples, so an online filter could run the same steps.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pandas as pd
from numpy.typing import ArrayLike, NDArray
from scipy.signal import lfilter

__all__ = ["RestParams", "detect_rest", "gyro_bias_at_rest"]

Array = NDArray[np.float64]


@dataclass(frozen=True)
class RestParams:
    """Thresholds (VQF's defaults where it has one: 2 °/s, 0.5 m/s², 1.5 s)."""

    gyro_dev_rad_s: float = math.radians(2.0)
    gyro_max_rad_s: float = math.radians(5.0)
    acc_dev_m_s2: float = 0.5
    min_rest_s: float = 1.5
    lowpass_tau_s: float = 0.5
    bias_tau_s: float = 2.0


def _lowpass(x: Array, alpha: float) -> Array:
    """First-order low-pass ``y_k = y_(k-1) + α(x_k - y_(k-1))`` started at x_0."""
    zi = ((1.0 - alpha) * x[0])[None, :]
    out, _ = lfilter([alpha], [1.0, alpha - 1.0], x, axis=0, zi=zi)
    return out


def _rest_mean(x: Array, n: int) -> Array:
    """Running mean of the first ``n`` samples, then a low-pass with time constant n samples.

    The mean makes the first estimate as good as the samples seen so far (a low-pass
    started at one noisy sample would not be); the low-pass then follows slow drift.
    """
    k = min(n, len(x))
    out = np.empty_like(x)
    out[:k] = np.cumsum(x[:k], axis=0) / np.arange(1, k + 1)[:, None]
    if len(x) > k:
        alpha = 1.0 / n
        zi = ((1.0 - alpha) * out[k - 1])[None, :]
        out[k:], _ = lfilter([alpha], [1.0, alpha - 1.0], x[k:], axis=0, zi=zi)
    return out


def detect_rest(t_s: ArrayLike, gyro: ArrayLike, acc: ArrayLike,
                params: RestParams = RestParams()) -> NDArray[np.bool_]:
    """Boolean rest mask (causal: sample k is judged from samples up to k)."""
    t = np.asarray(t_s, dtype=float)
    w = np.asarray(gyro, dtype=float)
    a = np.asarray(acc, dtype=float)
    if len(t) < 2:
        return np.zeros(len(t), dtype=bool)
    dt = float(np.median(np.diff(t)))
    alpha = min(1.0, dt / params.lowpass_tau_s)
    w_lp, a_lp = _lowpass(w, alpha), _lowpass(a, alpha)
    still = ((np.linalg.norm(w - w_lp, axis=1) < params.gyro_dev_rad_s)
             & (np.linalg.norm(w_lp, axis=1) < params.gyro_max_rad_s)
             & (np.linalg.norm(a - a_lp, axis=1) < params.acc_dev_m_s2))
    window = max(1, round(params.min_rest_s / dt))
    # at rest once the last `window` samples were all still (a causal rolling minimum)
    run = pd.Series(still.astype(float)).rolling(window, min_periods=window).min()
    return run.fillna(0.0).to_numpy() > 0.5


def gyro_bias_at_rest(t_s: ArrayLike, gyro: ArrayLike, acc: ArrayLike,
                      params: RestParams = RestParams(),
                      initial: ArrayLike | None = None) -> tuple[Array, NDArray[np.bool_]]:
    """Per-sample gyro bias ``(n, 3)`` (held between rests) and the rest mask.

    Before the first rest the bias is ``initial`` (zeros by default).
    """
    t = np.asarray(t_s, dtype=float)
    w = np.asarray(gyro, dtype=float)
    rest = detect_rest(t, w, acc, params)
    bias = np.tile(np.zeros(3) if initial is None else np.asarray(initial, float), (len(t), 1))
    idx = np.flatnonzero(rest)
    if idx.size:
        dt = float(np.median(np.diff(t)))
        b_rest = _rest_mean(w[idx], max(1, round(params.bias_tau_s / dt)))
        last = np.searchsorted(idx, np.arange(len(t)), side="right") - 1
        seen = last >= 0
        bias[seen] = b_rest[last[seen]]
    return bias, rest
