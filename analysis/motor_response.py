"""A motor's time constants from a flight log: command to speed, rising and falling apart.

In flight the command never steps cleanly, so the edges of a bench run are not there to
fit. What a flight log has is the command u and the speed w of each motor, sampled
together. A first-order actuator with a static map and a dead time, w + tau dw/dt =
g(u(t - d)) with g quadratic (C.2 with the static curve of C.13), is linear in its unknowns
once the derivative is known:

    w = a0 + a1 u_d + a2 u_d^2 - tau_up dw/dt [dw/dt > 0] - tau_down dw/dt [dw/dt < 0]

so one least-squares solve per dead time d gives the map and both time constants; the dead
time is the one of a grid (0-30 ms) that fits best. The speed is low-passed before it is
differentiated (a zero-phase Butterworth at ``SMOOTH_HZ``), and only samples where the
motor turns (above 10 % of its top speed) take part: below, the ESC's start-up and the
propeller's stall are not a first-order lag. Nor do samples near a hole in the log (no
command or speed for ``HOLE_SAMPLES`` sample periods: the logger dropped frames, a
software-in-the-loop firmware or its plant did not run): the grid bridges a hole with a
straight line, which is no response of the motor, and the low-pass and the dead time carry
it ``HOLE_MARGIN_S`` further.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.signal import butter, sosfiltfilt

__all__ = ["MotorResponse", "fit_motor_response"]

SMOOTH_HZ = 40.0  # speed low-pass before the derivative
DEAD_TIMES_S = np.arange(0.0, 0.0305, 0.0005)
MIN_SAMPLES = 200
HOLE_SAMPLES = 10  # a gap this many median sample periods long is a hole
HOLE_MARGIN_S = 1.0 / SMOOTH_HZ  # the low-pass's reach on either side of a hole


@dataclass(frozen=True)
class MotorResponse:
    """One motor: rising and falling time constants, dead time, map and fit quality."""

    motor: str
    tau_up_s: float
    tau_down_s: float
    dead_time_s: float
    map_coefficients: tuple[float, float, float]  # speed = a0 + a1 u + a2 u^2 (rpm)
    rms_rpm: float
    samples: int
    why: str = ""

    def summary(self) -> dict[str, Any]:
        return {"motor": self.motor, "tau_up_ms": self.tau_up_s * 1e3,
                "tau_down_ms": self.tau_down_s * 1e3, "dead_time_ms": self.dead_time_s * 1e3,
                "map_rpm": list(self.map_coefficients), "rms_rpm": self.rms_rpm,
                "samples": self.samples, **({"why": self.why} if self.why else {})}


def fit_motor_response(t_s: np.ndarray, command: np.ndarray, rpm: np.ndarray,
                       motor: str = "motor1") -> MotorResponse:
    """Fit the model of the module's docstring to one motor's command and speed."""
    t = np.asarray(t_s, float)
    u = np.asarray(command, float)
    w = np.asarray(rpm, float)
    ok = np.isfinite(t) & np.isfinite(u) & np.isfinite(w)
    nan = MotorResponse(motor, math.nan, math.nan, math.nan, (math.nan, math.nan, math.nan),
                        math.nan, 0)
    if ok.sum() < MIN_SAMPLES:
        return _why(nan, f"{int(ok.sum())} samples with command and speed (need "
                         f"{MIN_SAMPLES})")
    t, u, w = t[ok], u[ok], w[ok]
    # a speed held between slower updates (ESC telemetry under a faster gyro clock): its
    # own rate is how often it changes
    changes = int(np.count_nonzero(np.diff(w)))
    span = float(t[-1] - t[0])
    if span > 0 and changes / span <= 2.5 * SMOOTH_HZ:
        return _why(nan, f"speed updated at {changes / span:.0f} Hz: too slow to see a time "
                         "constant of tens of ms (needs > 100 Hz)")
    dt = float(np.median(np.diff(t)))
    if not dt > 0:
        return _why(nan, "the log's time does not advance")
    grid = np.arange(t[0], t[-1], dt)
    u = np.interp(grid, t, u)
    w = np.interp(grid, t, w)
    fs = 1.0 / dt
    if fs <= 2.5 * SMOOTH_HZ:
        return _why(nan, f"speed logged at {fs:.0f} Hz: too slow to see a time constant of "
                         "tens of ms (needs > 100 Hz)")
    near_hole = _near_holes(grid, t, HOLE_SAMPLES * dt, HOLE_MARGIN_S)
    # the same zero-phase low-pass on speed and on the map's regressors: a linear filter
    # commutes with the model, so the smoothed signals obey it too
    sos = butter(2, SMOOTH_HZ, fs=fs, output="sos")
    ws = sosfiltfilt(sos, w)
    dw = np.gradient(ws, dt)
    u1, u2 = sosfiltfilt(sos, u), sosfiltfilt(sos, u * u)
    turning = ws > 0.1 * np.nanmax(ws)
    best: tuple[float, np.ndarray, float, int] | None = None
    for d in DEAD_TIMES_S:
        k = round(d / dt)
        ud1 = np.concatenate((np.full(k, u1[0]), u1[:u1.size - k])) if k else u1
        ud2 = np.concatenate((np.full(k, u2[0]), u2[:u2.size - k])) if k else u2
        use = turning & ~near_hole
        if k:  # the command d earlier must be clear of holes too
            use[k:] &= ~near_hole[:-k]
        use[:k] = False
        if use.sum() < MIN_SAMPLES:
            continue
        rising = (dw > 0)[use]
        x = np.column_stack((np.ones(int(use.sum())), ud1[use], ud2[use],
                             -dw[use] * rising, -dw[use] * ~rising))
        coef, *_ = np.linalg.lstsq(x, ws[use], rcond=None)
        rms = float(np.sqrt(np.mean((x @ coef - ws[use]) ** 2)))
        if best is None or rms < best[0]:
            best = (rms, coef, float(d), int(use.sum()))
    if best is None:
        return _why(nan, "the motor hardly turns in this log")
    rms, coef, d, n = best
    return MotorResponse(motor, float(coef[3]), float(coef[4]), d,
                         (float(coef[0]), float(coef[1]), float(coef[2])), rms, n)


def _why(r: MotorResponse, why: str) -> MotorResponse:
    return MotorResponse(r.motor, r.tau_up_s, r.tau_down_s, r.dead_time_s,
                         r.map_coefficients, r.rms_rpm, r.samples, why)


def _near_holes(grid: np.ndarray, t: np.ndarray, gap: float, margin: float) -> np.ndarray:
    """Grid points strictly within ``margin`` of a hole (consecutive ``t`` more than
    ``gap`` apart), in one pass: each hole's span of the grid by a search, the spans
    merged by a running count (no pass over the grid per hole)."""
    holes = np.flatnonzero(np.diff(t) > gap)
    first = np.searchsorted(grid, t[holes] - margin, side="right")  # grid > t[h] - margin
    stop = np.searchsorted(grid, t[holes + 1] + margin, side="left")  # grid < t[h+1] + m
    count = np.zeros(grid.size + 1, np.int64)
    np.add.at(count, first, 1)
    np.add.at(count, np.maximum(stop, first), -1)
    return np.cumsum(count[:-1]) > 0
