"""Test helper: first-order-plus-dead-time fit of averaged thrust steps (Table C.1 style).

Tests only; the real identification module comes with a later issue.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from drivers.factory import OpenRig


@dataclass(frozen=True)
class Fopdt:
    delay_s: float
    tau_s: float
    rms: float


def fopdt_response(t: np.ndarray, delay: float, tau: float) -> np.ndarray:
    """Unit step response of exp(-delay s) / (tau s + 1)."""
    return np.where(t > delay, 1.0 - np.exp(-np.clip(t - delay, 0.0, None) / tau), 0.0)


def fit_fopdt(t: np.ndarray, y: np.ndarray) -> Fopdt:
    """Fit y (normalised 0 -> 1 step, t = 0 at the command) with delay and tau."""

    def resid(p: np.ndarray) -> np.ndarray:
        return fopdt_response(t, p[0], p[1]) * p[2] + p[3] - y

    sol = least_squares(resid, x0=[0.01, 0.03, 1.0, 0.0],
                        bounds=([0.0, 1e-3, 0.5, -0.5], [0.2, 1.0, 1.5, 0.5]))
    return Fopdt(float(sol.x[0]), float(sol.x[1]), float(np.sqrt(np.mean(sol.fun**2))))


def run_step1(rig: OpenRig, low_us: float, high_us: float, repeats: int, hold_s: float,
              tick_s: float = 0.0025) -> tuple[list[np.ndarray], list[np.ndarray], float]:
    """Paper C Step 1 on an open rig: low <-> high, ``repeats`` times; load-cell thrust.

    Returns the up-step and down-step segments (thrust at 25 kHz from the command on),
    and the sample rate.
    """
    cell = rig.sensors["load_cell"]
    rig.esc.arm()
    fs = cell.describe().channels[0].rate_hz
    n_hold = round(hold_s / tick_s)

    def hold(pulse: float) -> np.ndarray:
        out = []
        for _ in range(n_hold):
            rig.esc.set_pulse_us(pulse)
            rig.clock.sleep(tick_s)
            out.append(cell.read_block().values["thrust_n"])
        return np.concatenate(out)

    hold(low_us)
    up, down = [], []
    for _ in range(repeats):
        up.append(hold(high_us))
        down.append(hold(low_us))
    rig.esc.disarm()
    return up, down, fs


def average_and_fit(segments: list[np.ndarray], fs: float, window_s: float = 0.5,
                    bin_s: float = 0.0025) -> Fopdt:
    """Mean of the repeats, averaged per ESC period (Paper C 2.2), normalised, fitted."""
    n = round(window_s * fs)
    mean = np.mean([s[:n] for s in segments], axis=0)
    per_bin = round(bin_s * fs)
    binned = mean[: n // per_bin * per_bin].reshape(-1, per_bin).mean(axis=1)
    t = (np.arange(binned.size) + 0.5) * bin_s
    start = mean[: round(0.005 * fs)].mean()  # before the delay: the old level
    end = np.mean([s[-round(0.1 * fs):] for s in segments])  # settled new level
    y = (binned - start) / (end - start)
    return fit_fopdt(t, y)
