"""A flight's step response per axis, from its own log: setpoint to gyro by Wiener
deconvolution over many windows, as PID-Analyzer 0.52 estimates it, with the numbers
Flight Review reports.

PID-Analyzer's recipe (its ``Trace`` class): the log resampled onto a uniform grid; windows
of 1 s, a new one every 1/16 s, each Hann-weighted on input and gyro and zero-padded to a
multiple of 1024 samples; per window the impulse response
``Re IFFT(G H* / (H H* + 1/sn))`` with sn about 10 below 25 Hz and about 0 above (a
Gaussian-smoothed edge); the step response the cumulative sum of its first 0.5 s.
Windows whose setpoint never exceeds 20 deg/s carry no step and are dropped; those above
500 deg/s form a separate "high" set, used only with 10 or more windows. The responses are
averaged by a mode-seeking mean: a 2-D histogram (time x amplitude in [-1.5, 3.5]),
smoothed along the amplitude, each time column scaled to its maximum, the amplitude
averaged with the squared histogram as weights.

Flight Review's numbers on the averaged response: final = the mean of its last 40 %,
delay = time to 50 % of final, rise = t(90 %) - t(10 %), overshoot = (max - final) / final.

Beside it, Flight Review's own estimate (``h1``): the averaged cross-spectrum over the
averaged input spectrum (Welch, Hann segments of a power of two >= 2 s, 50 % overlap,
segments whose setpoint varies by less than 5 deg/s skipped), trusted up to where the
coherence drops below 0.6 (at least 5 Hz) and tapered to zero at twice that. The coherence
is judged averaged over neighbouring bins, each weighted by the input's power there (ours:
a bin at a null of the input's spectrum, as a train of equal stick pulses has, holds no
evidence either way, and its dip alone ended the band at 5.4 Hz on a Betaflight flight
whose coherence stood at 0.7-0.8 up to 20 Hz, its rise read 26 % long). On loops of
known response (tests/analysis/test_flight_response.py) it is the nearer of the two: the
per-window deconvolution applies one Hann window to input and output alike, which a
slow loop's lagging answer does not obey, and its 25 Hz cut-off rings; so the headline
numbers are the H1 ones, and PID-Analyzer's are reported beside them.

Vectorised: every window of an axis is one 2-D array, transformed at once.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.ndimage import gaussian_filter1d

from analysis.stick_steps import GAP_S

__all__ = ["AxisResponse", "flight_step_responses", "response_metrics"]

FRAME_S = 1.0  # window length (PA framelen)
RESPONSE_S = 0.5  # step response kept (PA resplen)
SUPERPOS = 16  # windows per frame length (PA superpos)
CUTOFF_HZ = 25.0  # PA cutfreq: the deconvolution trusts the input below it
SN_LOW = 10.0  # PA signal-to-noise below the cut-off
MIN_INPUT_DPS = 20.0  # a window whose setpoint stays below this holds no step
HIGH_INPUT_DPS = 500.0  # above: the "high" set
MIN_HIGH_WINDOWS = 10
HIST_BINS = 1000
HIST_RANGE = (-1.5, 3.5)
HIST_SIGMA = 7.0  # bins, along the amplitude
#: a response whose final value is outside this never followed its setpoint (a vehicle on
#: the ground, an axis without stick input): no numbers (PIDtoolbox's quality gate keeps
#: 0.5 < response < 3 over 200-500 ms for the same reason)
FINAL_RANGE = (0.5, 2.0)


@dataclass(frozen=True)
class AxisResponse:
    """One axis: the step response by both estimates and the windows they came from."""

    axis: str
    t_s: np.ndarray
    step: np.ndarray | None  # H1 (Flight Review), the headline
    windows: int  # PID-Analyzer's windows with a stick input
    windows_high: int
    step_high: np.ndarray | None
    metrics: dict[str, float]  # of ``step``
    why: str = ""
    step_pa: np.ndarray | None = None  # PID-Analyzer's mode-averaged deconvolution
    metrics_pa: dict[str, float] | None = None
    segments: int = 0  # H1's segments with a stick input
    trusted_hz: float = math.nan  # H1's coherence cut-off

    def summary(self) -> dict[str, Any]:
        return {"axis": self.axis, **self.metrics, "h1_segments": self.segments,
                "h1_trusted_hz": self.trusted_hz,
                "pid_analyzer": {**(self.metrics_pa or {}), "windows": self.windows,
                                 "windows_high": self.windows_high},
                **({"why": self.why} if self.why else {})}


def _resample(t: np.ndarray, y: np.ndarray, grid: np.ndarray) -> np.ndarray:
    """``y`` on ``grid``, NaN inside a gap of the log (rows more than ``GAP_S`` apart: the
    firmware did not run, as a software-in-the-loop one on a loaded host may not): a
    straight line across it is no answer of the loop, and a window holding it is dropped."""
    ok = np.isfinite(t) & np.isfinite(y)
    if ok.sum() < 2:
        return np.full(grid.size, np.nan)
    tk = t[ok]
    out = np.interp(grid, tk, y[ok])
    k = np.clip(np.searchsorted(tk, grid), 1, tk.size - 1)
    out[tk[k] - tk[k - 1] > GAP_S] = np.nan
    return out


def _sn_profile(n_fft: int, dt: float) -> np.ndarray:
    """1/sn per rfft bin: 1/SN_LOW below the cut-off, a very large number above, the edge
    smoothed by a Gaussian of a sixth of the bins below the cut-off (PA)."""
    freqs = np.fft.rfftfreq(n_fft, dt)
    below = freqs <= CUTOFF_HZ
    sn = np.where(below, SN_LOW, 1e-9)
    width = max(int(below.sum()) / 6.0, 1.0)
    sn = gaussian_filter1d(sn, width, mode="nearest")
    return 1.0 / np.maximum(sn, 1e-9)


def _window_steps(inp: np.ndarray, out: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Step responses of every window (rows) and each window's largest |input| (deg/s)."""
    n = round(FRAME_S / dt)
    hop = max(round(n / SUPERPOS), 1)
    if inp.size < n:
        return np.empty((0, round(RESPONSE_S / dt))), np.empty(0)
    starts = np.arange(0, inp.size - n + 1, hop)
    idx = starts[:, None] + np.arange(n)[None, :]
    win = np.hanning(n)
    x, y = inp[idx], out[idx]
    good = np.isfinite(x).all(axis=1) & np.isfinite(y).all(axis=1)
    x, y = x[good] * win, y[good] * win
    peak = np.abs(inp[idx][good]).max(axis=1) if good.any() else np.empty(0)  # deg/s
    n_fft = int(math.ceil(n / 1024) * 1024)  # zero-padded to a multiple of 1024 (PA)
    h = np.fft.rfft(x, n_fft, axis=1)
    g = np.fft.rfft(y, n_fft, axis=1)
    inv_sn = _sn_profile(n_fft, dt)
    impulse = np.fft.irfft(g * h.conj() / (np.abs(h) ** 2 + inv_sn), n_fft, axis=1)
    keep = round(RESPONSE_S / dt)
    return np.cumsum(impulse[:, :keep], axis=1), peak


def _mode_average(steps: np.ndarray) -> np.ndarray:
    """PA's weighted mode average of many responses (rows), column by column."""
    lo, hi = HIST_RANGE
    edges = np.linspace(lo, hi, HIST_BINS + 1)
    centres = 0.5 * (edges[:-1] + edges[1:])
    k = np.clip(np.searchsorted(edges, steps, side="right") - 1, 0, HIST_BINS - 1)
    cols = np.broadcast_to(np.arange(steps.shape[1]), steps.shape)
    hist = np.zeros((steps.shape[1], HIST_BINS))
    np.add.at(hist, (cols.ravel(), k.ravel()), 1.0)
    hist = gaussian_filter1d(hist, HIST_SIGMA, axis=1, mode="constant")
    hist /= np.maximum(hist.max(axis=1, keepdims=True), 1e-300)
    w = hist * hist
    return (w * centres).sum(axis=1) / np.maximum(w.sum(axis=1), 1e-300)


H1_MIN_S = 2.0  # Flight Review: segments of a power of two >= 2 s
H1_MIN_STD_DPS = 5.0  # a segment whose setpoint varies less holds no input
COHERENCE_MIN = 0.6
COHERENCE_SMOOTH_BINS = 3.0  # Gaussian sigma (bins) of the coherence's power-weighted average
TRUST_MIN_HZ = 5.0


def _h1_step(inp: np.ndarray, out: np.ndarray, dt: float, keep: int
             ) -> tuple[np.ndarray | None, int, float]:
    """Flight Review's H1 step response: (step, segments used, trusted bandwidth Hz)."""
    n = 1 << math.ceil(math.log2(max(H1_MIN_S / dt, 2.5 * keep)))
    if inp.size < n:
        return None, 0, math.nan
    starts = np.arange(0, inp.size - n + 1, n // 2)
    idx = starts[:, None] + np.arange(n)[None, :]
    x, y = inp[idx], out[idx]
    good = (np.isfinite(x).all(axis=1) & np.isfinite(y).all(axis=1)
            & (np.nan_to_num(x).std(axis=1) >= H1_MIN_STD_DPS))
    if not good.any():
        return None, 0, math.nan
    win = np.hanning(n)
    xs, ys = x[good], y[good]
    h = np.fft.rfft((xs - xs.mean(axis=1, keepdims=True)) * win, axis=1)
    g = np.fft.rfft((ys - ys.mean(axis=1, keepdims=True)) * win, axis=1)
    pxy = (g * h.conj()).mean(axis=0)
    pxx = (np.abs(h) ** 2).mean(axis=0)
    pyy = (np.abs(g) ** 2).mean(axis=0)
    freqs = np.fft.rfftfreq(n, dt)
    coh = np.abs(pxy) ** 2 / np.maximum(pxx * pyy, 1e-300)
    # the coherence smoothed over neighbouring bins weighted by the input's power there: at
    # a null of the input's spectrum (a 0.25 s stick pulse has one at 4 Hz) a bin's
    # coherence is noise over nothing, and its dip ended the trusted band at 5.4 Hz on a
    # log whose coherence stood at 0.7-0.8 up to 20 Hz
    smooth = (gaussian_filter1d(coh * pxx, COHERENCE_SMOOTH_BINS, mode="nearest")
              / np.maximum(gaussian_filter1d(pxx, COHERENCE_SMOOTH_BINS, mode="nearest"),
                           1e-300))
    low = np.flatnonzero((smooth < COHERENCE_MIN) & (freqs >= TRUST_MIN_HZ))
    f_trust = float(freqs[low[0]]) if low.size else float(freqs[-1])
    taper = np.where(freqs <= f_trust, 1.0, np.where(
        freqs >= 2 * f_trust, 0.0, 0.5 * (1 + np.cos(np.pi * (freqs - f_trust) / f_trust))))
    transfer = pxy / np.maximum(pxx, 1e-300) * taper
    impulse = np.fft.irfft(transfer, n)
    return np.cumsum(impulse[:keep]), int(good.sum()), f_trust


def response_metrics(t: np.ndarray, step: np.ndarray) -> dict[str, float]:
    """Flight Review's numbers (ms and %): delay to 50 % of final, 10-90 % rise,
    overshoot over final; final is the mean of the last 40 %."""
    final = float(np.mean(step[int(0.6 * step.size):]))
    if not math.isfinite(final) or final <= 0:
        return {"final": final, "delay_ms": math.nan, "rise_ms": math.nan,
                "overshoot_pct": math.nan}

    def first(frac: float) -> float:
        above = np.flatnonzero(step >= frac * final)
        if not above.size:
            return math.nan
        j = int(above[0])
        if j == 0:
            return float(t[0])
        f = (frac * final - step[j - 1]) / (step[j] - step[j - 1])
        return float(t[j - 1] + f * (t[j] - t[j - 1]))

    return {"final": final, "delay_ms": first(0.5) * 1e3,
            "rise_ms": (first(0.9) - first(0.1)) * 1e3,
            "overshoot_pct": (float(np.max(step)) - final) / final * 100.0}


def flight_step_responses(t_s: np.ndarray, setpoint: dict[str, np.ndarray],
                          gyro: dict[str, np.ndarray], rate_hz: float | None = None
                          ) -> dict[str, AxisResponse]:
    """Per axis (``x``, ``y``, ``z``): setpoint and gyro in rad/s on times ``t_s``."""
    t_s = np.asarray(t_s, dtype=float)
    span = float(np.nanmax(t_s) - np.nanmin(t_s)) if t_s.size else 0.0
    if rate_hz is None:
        d = np.diff(t_s[np.isfinite(t_s)])
        rate_hz = 1.0 / float(np.median(d[d > 0])) if (d > 0).any() else 0.0
    rate_hz = min(rate_hz, 4000.0)  # PA resamples; beyond this nothing the loop answers
    out: dict[str, AxisResponse] = {}
    keep = round(RESPONSE_S * rate_hz) if rate_hz > 0 else 0
    t_resp = np.arange(keep) / rate_hz if keep else np.empty(0)
    for axis in setpoint:
        empty = AxisResponse(axis, t_resp, None, 0, 0, None, {})
        if rate_hz <= 0 or span < FRAME_S:
            out[axis] = _why(empty, f"the log is {span:.2f} s long: a window needs "
                                    f"{FRAME_S:g} s")
            continue
        grid = np.arange(float(np.nanmin(t_s)), float(np.nanmax(t_s)), 1.0 / rate_hz)
        # in deg/s, as PA deconvolves: its noise term is sized for those numbers
        inp = np.degrees(_resample(t_s, np.asarray(setpoint[axis], float), grid))
        resp = np.degrees(_resample(t_s, np.asarray(gyro[axis], float), grid))
        steps, peak = _window_steps(inp, resp, 1.0 / rate_hz)
        low = (peak > MIN_INPUT_DPS) & (peak <= HIGH_INPUT_DPS)
        high = peak > HIGH_INPUT_DPS
        h1, segments, trusted = _h1_step(inp, resp, 1.0 / rate_hz, keep)
        if h1 is None and bool(np.isnan(inp).any()):
            out[axis] = _why(empty, f"no {H1_MIN_S:g} s segment free of gaps (missing "
                                    f"values, rows more than {1e3 * GAP_S:.0f} ms apart) "
                                    "with stick input")
            continue
        if (not low.any() and high.sum() < MIN_HIGH_WINDOWS) or h1 is None:
            out[axis] = _why(empty, f"no window's setpoint exceeds {MIN_INPUT_DPS:g} deg/s: "
                                    "no stick input to respond to")
            continue
        final = response_metrics(t_resp, h1)["final"]
        if not FINAL_RANGE[0] <= final <= FINAL_RANGE[1]:
            out[axis] = _why(empty, f"the gyro does not follow the setpoint (the response "
                                    f"settles at {final:.2f} of it, {segments} segments): "
                                    "on the ground, or too little stick input")
            continue
        use = low if low.any() else high
        step_pa = _mode_average(steps[use])
        step_high = _mode_average(steps[high]) if high.sum() >= MIN_HIGH_WINDOWS else None
        out[axis] = AxisResponse(axis, t_resp, h1, int(use.sum()), int(high.sum()),
                                 step_high, response_metrics(t_resp, h1),
                                 step_pa=step_pa,
                                 metrics_pa=response_metrics(t_resp, step_pa),
                                 segments=segments, trusted_hz=trusted)
    return out


def _why(r: AxisResponse, why: str) -> AxisResponse:
    return AxisResponse(r.axis, r.t_s, None, 0, 0, None, {}, why)
