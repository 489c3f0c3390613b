"""Vibration of a propulsion run: its level against speed, and its spectrum.

Vibration against speed is a standard stand measurement (Tyto's software plots it). Two
sources, in this order:

* a stand's own vibration level (RCbenchmark ``Vibration (g)`` -> ``vibration_m_s2``),
  taken as logged: the median of each speed bin;
* accelerometer axes (``acc_x_m_s2``, ``acc_y_m_s2``, ``acc_z_m_s2``; the simulated
  rig's load-cell mount gives ``acc_x_m_s2``): the RMS of their fluctuation about the bin
  mean, axes summed in quadrature. Gravity and a tilted mount are constant, so they drop out.

A spectrum (Welch's PSD, ``scipy.signal.welch``) is only honest where the samples are
evenly spaced and the rate resolves what the rotor makes: the rotor frequency
``rpm / 60`` and the blade-pass frequency ``blades x rpm / 60``. It is computed on the
longest stretch held at the run's top steady speed, and refused (``LogError`` saying
why) when the rate is below ``RATE_MARGIN`` x the blade-pass frequency or the sampling is
uneven: a stand log at ~40 Hz (RCbenchmark 1580) folds a 250 Hz rotor line to some
arbitrary low frequency, which would read as a real peak.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd
from scipy.signal import welch

from analysis.errors import LogError

__all__ = ["ACC_COLUMNS", "RATE_MARGIN", "VibrationCurve", "VibrationSpectrum",
           "vibration_spectrum", "vibration_vs_speed"]

ACC_COLUMNS = ("acc_x_m_s2", "acc_y_m_s2", "acc_z_m_s2")
LEVEL_COLUMN = "vibration_m_s2"
RATE_MARGIN = 2.5  # sample rate >= 2.5 x blade pass: the line sits below 0.4 fs (Nyquist 0.5)
MIN_RPM = 300.0  # slower is "not turning" for vibration purposes
HOLD_TOL = 0.01  # a steady hold: speed within +-1 % of the target (a ramp is no hold)
MIN_HOLD_S = 0.5  # and at least this long (2 Hz resolution with one Welch segment)
MAX_JITTER = 0.1  # evenly sampled: every step within 10 % of the median step


@dataclass(frozen=True)
class VibrationCurve:
    """Vibration level per speed bin (bins with at least 3 samples)."""

    source: str  # the column(s) the level comes from
    kind: str  # "logged level" or "rms of acceleration"
    rpm: np.ndarray  # median speed of each bin
    level_m_s2: np.ndarray
    samples: np.ndarray  # samples per bin

    def summary(self) -> dict[str, object]:
        return {"source": self.source, "kind": self.kind, "rpm": self.rpm.tolist(),
                "level_m_s2": self.level_m_s2.tolist(), "samples": self.samples.tolist()}


@dataclass(frozen=True)
class VibrationSpectrum:
    """Welch PSD of one acceleration column over a steady hold."""

    column: str
    f_hz: np.ndarray
    psd: np.ndarray  # (m/s^2)^2 / Hz
    fs_hz: float
    rpm: float  # median speed of the hold
    blades: int
    t0_s: float
    t1_s: float

    @property
    def rotor_hz(self) -> float:
        return self.rpm / 60.0

    @property
    def blade_pass_hz(self) -> float:
        return self.blades * self.rotor_hz

    @property
    def peak_hz(self) -> float:
        """The strongest line above half the rotor frequency (below it: drift, the mean)."""
        band = self.f_hz >= 0.5 * self.rotor_hz
        return float(self.f_hz[band][np.argmax(self.psd[band])])

    def summary(self) -> dict[str, float | int | str]:
        return {"column": self.column, "fs_hz": self.fs_hz, "rpm": self.rpm,
                "rotor_hz": self.rotor_hz, "blade_pass_hz": self.blade_pass_hz,
                "blades": self.blades, "peak_hz": self.peak_hz, "t0_s": self.t0_s,
                "t1_s": self.t1_s, "resolution_hz": float(self.f_hz[1] - self.f_hz[0])}


def _present(samples: pd.DataFrame, col: str) -> bool:
    return col in samples.columns and bool(np.isfinite(samples[col].to_numpy(float)).any())


def vibration_vs_speed(samples: pd.DataFrame, bins: int = 12) -> VibrationCurve | None:
    """The level per speed bin, or None when the run has no vibration column or never
    turns. ``bins`` equal bins between the slowest and fastest turning sample."""
    axes = [c for c in ACC_COLUMNS if _present(samples, c)]
    level = _present(samples, LEVEL_COLUMN)
    if "rpm" not in samples.columns or not (level or axes):
        return None
    rpm = samples["rpm"].to_numpy(float)
    turning = np.isfinite(rpm) & (rpm > MIN_RPM)
    if not turning.any():
        return None
    lo, hi = float(rpm[turning].min()), float(rpm[turning].max())
    edges = np.linspace(lo, hi, bins + 1) if hi > lo else np.array([lo, lo + 1.0])
    k = np.clip(np.searchsorted(edges, rpm, side="right") - 1, 0, len(edges) - 2)
    cols = [LEVEL_COLUMN] if level else axes
    df = pd.DataFrame({"bin": k, "rpm": rpm, **{c: samples[c].to_numpy(float) for c in cols}})
    df = df[turning].dropna()
    g = df.groupby("bin")
    n = g.size().to_numpy()  # every per-bin result below is in the same (bin) order
    if level:
        value = np.asarray(g[LEVEL_COLUMN].median(), dtype=float)
    else:  # per-bin variance of each axis about its own mean, summed over the axes
        value = np.sqrt(np.sum([np.asarray(g[c].var(ddof=0), dtype=float) for c in axes], axis=0))
    keep = n >= 3
    if not keep.any():
        return None
    return VibrationCurve(
        source=", ".join(cols), kind="logged level" if level else "rms of acceleration",
        rpm=np.asarray(g["rpm"].median())[keep], level_m_s2=value[keep], samples=n[keep])


def _longest_true(mask: np.ndarray) -> tuple[int, int]:
    """[start, end) of the longest run of True in ``mask`` (vectorised)."""
    d = np.diff(np.concatenate(([0], mask.astype(np.int8), [0])))
    starts, ends = np.flatnonzero(d == 1), np.flatnonzero(d == -1)
    if starts.size == 0:
        return 0, 0
    i = int(np.argmax(ends - starts))
    return int(starts[i]), int(ends[i])


def vibration_spectrum(samples: pd.DataFrame, blades: int,
                       column: str | None = None) -> VibrationSpectrum:
    """Welch PSD of an acceleration column over the longest hold at the run's top steady
    speed (the 90th percentile of the turning speeds, +-1 %). ``LogError`` says why not:
    no accelerometer, no hold of ``MIN_HOLD_S``, uneven sampling, or a rate below
    ``RATE_MARGIN`` x the blade-pass frequency."""
    if blades < 1:
        raise LogError(f"blades: expected a whole number >= 1, got {blades}")
    if column is None:
        column = next((c for c in ACC_COLUMNS if _present(samples, c)), None)
        if column is None:
            raise LogError("no accelerometer column (acc_x_m_s2, acc_y_m_s2, acc_z_m_s2)")
    t = samples["t_s"].to_numpy(float)
    rpm = samples["rpm"].to_numpy(float) if "rpm" in samples.columns else np.full(t.size,
                                                                                   np.nan)
    acc = samples[column].to_numpy(float)
    ok = np.isfinite(t) & np.isfinite(rpm) & np.isfinite(acc)
    turning = ok & (rpm > MIN_RPM)
    if not turning.any():
        raise LogError("the rotor never turns (rpm)")
    target = float(np.percentile(rpm[turning], 90))
    a, b = _longest_true(ok & (np.abs(rpm - target) <= HOLD_TOL * target))
    held = float(t[b - 1] - t[a]) if b > a else 0.0
    if held < MIN_HOLD_S:
        raise LogError(f"no steady speed held for {MIN_HOLD_S:g} s near {target:.0f} rpm "
                       f"(longest {held:.2f} s)")
    dt = np.diff(t[a:b])
    step = float(np.median(dt))
    fs = 1.0 / step
    hold_rpm = float(np.median(rpm[a:b]))
    rotor_hz = hold_rpm / 60.0
    need = RATE_MARGIN * blades * rotor_hz
    if fs < need:
        raise LogError(f"{column} sampled at {fs:.3g} Hz (Nyquist {fs / 2:.3g} Hz), but the "
                       f"rotor turns at {rotor_hz:.0f} Hz ({hold_rpm:.0f} rpm) and its "
                       f"{blades} blades pass at {blades * rotor_hz:.0f} Hz: a spectrum needs "
                       f">= {need:.0f} Hz")
    if np.max(np.abs(dt - step)) > MAX_JITTER * step:
        raise LogError(f"{column} is not evenly sampled over the hold (steps "
                       f"{dt.min() * 1e3:.3g}-{dt.max() * 1e3:.3g} ms)")
    nperseg = min(b - a, round(fs * MIN_HOLD_S))
    f, p = welch(acc[a:b], fs=fs, nperseg=nperseg, detrend="constant")
    return VibrationSpectrum(column, f, p, fs, hold_rpm, int(blades), float(t[a]),
                             float(t[b - 1]))
