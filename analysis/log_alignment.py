"""Two recordings of the same signals on two clocks: the offset between the clocks.

A bench that runs a flight controller in the loop records what the controller sent on its
own (host) clock, and the controller logs the same outputs on its clock, whose zero the
host never learns (a firmware's start). Where both series change together, the offset is
the shift that lines their changes up: the peak of their cross-correlation on a common
grid, summed over the channels, refined between grid points by a parabola through the
peak and its neighbours. Differences, not levels, are correlated: a slow drift of the
level shared by both would otherwise flatten the peak.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.signal import correlate, correlation_lags

__all__ = ["ClockOffset", "clock_offset"]

GRID_S = 1e-3


@dataclass(frozen=True)
class ClockOffset:
    """``offset_s``: a time on clock B plus this is the same instant on clock A.
    ``r``: the correlation of the channels' changes at that offset (1: the same series)."""

    offset_s: float
    r: float


def _on_grid(t: np.ndarray, x: np.ndarray, dt: float) -> tuple[float, np.ndarray]:
    grid = np.arange(t[0], t[-1], dt)
    cols = [np.diff(np.interp(grid, t, x[:, k])) for k in range(x.shape[1])]
    return float(grid[0]), np.column_stack(cols)


def clock_offset(t_a: np.ndarray, x_a: np.ndarray, t_b: np.ndarray, x_b: np.ndarray, *,
                 dt: float = GRID_S) -> ClockOffset:
    """The offset of clock A over clock B (module doc). ``t_*`` increasing seconds,
    ``x_*`` one column per channel (the same channels, in the same order)."""
    xa = np.asarray(x_a, float).reshape(len(t_a), -1)
    xb = np.asarray(x_b, float).reshape(len(t_b), -1)
    a0, a = _on_grid(np.asarray(t_a, float), xa, dt)
    b0, b = _on_grid(np.asarray(t_b, float), xb, dt)
    a -= a.mean(axis=0)
    b -= b.mean(axis=0)
    corr = np.sum([correlate(a[:, k], b[:, k], mode="full", method="fft")
                   for k in range(a.shape[1])], axis=0)
    lags = correlation_lags(len(a), len(b), mode="full")
    i = int(np.argmax(corr))
    frac = 0.0
    if 0 < i < corr.size - 1:
        y0, y1, y2 = corr[i - 1], corr[i], corr[i + 1]
        den = y0 - 2.0 * y1 + y2
        frac = 0.5 * (y0 - y2) / den if den < 0 else 0.0
    lag = int(lags[i])
    # the overlap at that lag: a[j + lag] against b[j]
    j0, j1 = max(0, -lag), min(len(b), len(a) - lag)
    pa, pb = a[j0 + lag:j1 + lag].ravel(), b[j0:j1].ravel()
    den = float(np.sqrt(np.sum(pa * pa) * np.sum(pb * pb)))
    r = float(np.sum(pa * pb) / den) if den > 0 else 0.0
    return ClockOffset(a0 - b0 + (lag + frac) * dt, r)
