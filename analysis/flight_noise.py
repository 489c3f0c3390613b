"""Gyro noise against throttle from a flight log: where the rotor and blade-pass lines sit.

PID-Analyzer's noise plot, in numbers: the gyro cut into 0.3 s Hann windows (half
overlapping), each window's power spectrum filed under its mean throttle (20 bins from 0
to 1), the spectra of a bin averaged. A log with motor speeds adds, per throttle bin, the
median rotor frequency (rpm / 60) and its blade-pass multiple, so a line in the map can
be named. Vectorised: every window of an axis is one array, transformed at once.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = ["NoiseMap", "gyro_noise_vs_throttle"]

WINDOW_S = 0.3
THROTTLE_BINS = 20


@dataclass(frozen=True)
class NoiseMap:
    """Mean gyro PSD ((rad/s)^2/Hz) per axis, throttle bin x frequency."""

    freqs_hz: np.ndarray
    throttle_edges: np.ndarray
    psd: dict[str, np.ndarray]  # axis -> (bins, freqs); NaN rows: no window there
    windows: np.ndarray  # windows per bin
    rotor_hz: np.ndarray  # median rotor frequency per bin (NaN without speeds)

    def peaks(self, axis: str, blades: int = 2) -> list[dict[str, Any]]:
        """The strongest line of each populated bin, and the rotor lines beside it."""
        out = []
        for b in np.flatnonzero(self.windows):
            row = self.psd[axis][b]
            k = int(np.nanargmax(row[1:])) + 1  # not the DC bin
            out.append({"throttle": float(0.5 * (self.throttle_edges[b]
                                                 + self.throttle_edges[b + 1])),
                        "windows": int(self.windows[b]), "peak_hz": float(self.freqs_hz[k]),
                        "rotor_hz": float(self.rotor_hz[b]),
                        "blade_pass_hz": float(blades * self.rotor_hz[b])})
        return out


def gyro_noise_vs_throttle(t_s: np.ndarray, gyro: dict[str, np.ndarray],
                           throttle: np.ndarray, rpm: np.ndarray | None = None
                           ) -> NoiseMap | None:
    """The map, or None when the log is shorter than a window or has no throttle."""
    t = np.asarray(t_s, float)
    d = np.diff(t[np.isfinite(t)])
    if t.size < 4 or not (d > 0).any():
        return None
    fs = 1.0 / float(np.median(d[d > 0]))
    n = round(WINDOW_S * fs)
    thr = np.asarray(throttle, float)
    if n < 8 or t.size < n or not np.isfinite(thr).any():
        return None
    starts = np.arange(0, t.size - n + 1, n // 2)
    idx = starts[:, None] + np.arange(n)[None, :]
    mean_thr = np.nanmean(thr[idx], axis=1)
    edges = np.linspace(0.0, 1.0, THROTTLE_BINS + 1)
    which = np.clip(np.searchsorted(edges, mean_thr, side="right") - 1, 0, THROTTLE_BINS - 1)
    valid = np.isfinite(mean_thr)
    win = np.hanning(n)
    scale = 2.0 / (fs * float((win * win).sum()))  # one-sided PSD
    freqs = np.fft.rfftfreq(n, 1.0 / fs)
    counts = np.bincount(which[valid], minlength=THROTTLE_BINS)
    psd: dict[str, np.ndarray] = {}
    for axis, g in gyro.items():
        x = np.asarray(g, float)[idx]
        ok = valid & np.isfinite(x).all(axis=1)
        x = x[ok] - x[ok].mean(axis=1, keepdims=True)
        p = np.abs(np.fft.rfft(x * win, axis=1)) ** 2 * scale
        total = np.zeros((THROTTLE_BINS, freqs.size))
        np.add.at(total, which[ok], p)
        c = np.bincount(which[ok], minlength=THROTTLE_BINS)[:, None]
        with np.errstate(invalid="ignore", divide="ignore"):
            psd[axis] = np.where(c > 0, total / c, np.nan)
    rotor = np.full(THROTTLE_BINS, np.nan)
    if rpm is not None and np.isfinite(rpm).any():
        win_rpm = np.nanmedian(np.asarray(rpm, float)[idx], axis=1) / 60.0
        for b in np.flatnonzero(counts):
            vals = win_rpm[valid & (which == b)]
            vals = vals[np.isfinite(vals)]
            if vals.size:
                rotor[b] = float(np.median(vals))
    return NoiseMap(freqs, edges, psd, counts, rotor)
