"""The flight step response (Wiener deconvolution over windows, PID-Analyzer's recipe)
on a synthetic flight whose rate loop is a known system: its numbers come out as the
system's own step response gives them."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import signal

from analysis.flight_response import flight_step_responses, response_metrics

RATE = 2000.0


def _loop(wn_hz: float, zeta: float, delay_s: float) -> signal.TransferFunction:
    wn = 2 * np.pi * wn_hz
    return signal.TransferFunction([wn * wn], [1.0, 2 * zeta * wn, wn * wn]), delay_s


def _fly(seed: int, seconds: float = 40.0, loops: dict | None = None):
    """Stick steps of random size every 0.15-0.6 s on each axis, the gyro the loop's
    answer (delayed), plus gyro noise; rad/s."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, seconds, 1.0 / RATE)
    sp, gy = {}, {}
    for axis, (tf, delay) in (loops or {}).items():
        u = np.zeros(t.size)
        k = 0
        while k < t.size:
            n = int(rng.uniform(0.15, 0.6) * RATE)
            u[k:k + n] = np.radians(rng.uniform(-400, 400))
            k += n
        _, y, _ = signal.lsim(tf, u, t)
        y = np.interp(t - delay, t, y, left=0.0)
        sp[axis] = u
        gy[axis] = y + rng.normal(0.0, np.radians(3.0), t.size)
    return t, sp, gy


def test_the_response_of_a_known_loop_is_recovered():
    """H1 (the headline) within 2 ms, 5 % and 2 points of the loop's own step response;
    PID-Analyzer's deconvolution beside it, biased as its windowing makes it: further
    from the truth on every axis, most on the slow yaw-like loop."""
    loops = {"x": _loop(12.0, 0.5, 0.004), "y": _loop(20.0, 0.8, 0.002),
             "z": _loop(6.0, 0.7, 0.003)}
    t, sp, gy = _fly(1, loops=loops)
    res = flight_step_responses(t, sp, gy)
    for axis, (tf, delay) in loops.items():
        r = res[axis]
        assert r.windows > 300, r.summary()
        tt = r.t_s
        _, truth = signal.step(tf, T=tt)
        truth = np.interp(tt - delay, tt, truth, left=0.0)
        want = response_metrics(tt, truth)
        got, pa = r.metrics, r.metrics_pa
        assert got["final"] == pytest.approx(1.0, abs=0.04)
        assert got["delay_ms"] == pytest.approx(want["delay_ms"], abs=2.0)
        assert got["rise_ms"] == pytest.approx(want["rise_ms"], rel=0.05)
        assert got["overshoot_pct"] == pytest.approx(want["overshoot_pct"], abs=2.0)
        off = {k: abs(got[k] - want[k]) for k in ("delay_ms", "rise_ms", "overshoot_pct")}
        off_pa = {k: abs(pa[k] - want[k]) for k in off}
        assert sum(off_pa.values()) > sum(off.values()), (axis, got, pa, want)
    assert res["x"].metrics["overshoot_pct"] > res["y"].metrics["overshoot_pct"] + 5


def test_no_stick_input_or_a_short_log_says_why():
    t = np.arange(0.0, 5.0, 1 / RATE)
    calm = {"x": np.radians(5.0) * np.sin(t)}
    r = flight_step_responses(t, calm, calm)["x"]
    assert r.step is None and "no stick input" in r.why
    short = flight_step_responses(t[:1000], calm, calm)["x"]
    assert short.step is None and "a window needs 1 s" in short.why


def test_a_gap_in_the_log_is_left_out_not_bridged():
    """A firmware that stopped for 0.2 s now and then (its rows missing): the windows
    holding a gap are dropped, not bridged by a straight line, so the response is the
    gap-free one's; a log that is all gaps gives none, and says why."""
    loops = {"x": _loop(12.0, 0.6, 0.004)}
    t, sp, gy = _fly(3, 40.0, loops)
    clean = flight_step_responses(t, sp, gy)["x"]
    keep = np.ones(t.size, bool)
    for start in np.arange(1.0, 40.0, 8.0):  # 5 gaps: most 2 s segments stay whole
        keep &= ~((t >= start) & (t < start + 0.2))
    gapped = flight_step_responses(t[keep], {"x": sp["x"][keep]}, {"x": gy["x"][keep]})
    assert gapped["x"].segments < clean.segments
    assert gapped["x"].metrics["rise_ms"] == pytest.approx(clean.metrics["rise_ms"], rel=0.05)
    every = np.ones(t.size, bool)
    for start in np.arange(0.5, 40.0, 1.0):
        every &= ~((t >= start) & (t < start + 0.05))
    none = flight_step_responses(t[every], {"x": sp["x"][every]}, {"x": gy["x"][every]})["x"]
    assert none.step is None and "gaps" in (none.why or "")


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_a_null_of_the_stick_pulses_spectrum_does_not_end_the_trusted_band(seed: int):
    """A train of equal 0.25 s rate pulses (the bench's Betaflight program) has no input at
    4 Hz; where the gyro has power there of its own (a flight's other maneuvers, the
    pilot's height: here 20 deg/s of 3-5.5 Hz disturbance), that bin's coherence is near
    zero. The band is judged on the coherence weighted by the input's power, so it reaches
    past the null and the rise is the loop's; with the per-bin coherence smoothed alone the
    band ended at 5.4 Hz and the rise read 45 % long (a Betaflight flight's pitch: 26 %)."""
    rng = np.random.default_rng(seed)
    tf, delay = _loop(8.0, 0.3, 0.003)
    t = np.arange(0.0, 30.0, 1.0 / RATE)
    u = np.zeros(t.size)
    for k, start in enumerate(np.arange(0.5, 29.0, 1.2)):
        u[(t >= start) & (t < start + 0.25)] = np.radians(100.0 if k % 2 == 0 else -100.0)
    _, y, _ = signal.lsim(tf, u, t)
    band = signal.butter(2, [3.0 / (RATE / 2), 5.5 / (RATE / 2)], btype="band")
    d = signal.lfilter(*band, rng.normal(0.0, 1.0, t.size))
    y = (np.interp(t - delay, t, y, left=0.0) + np.radians(20.0) * d / d.std()
         + rng.normal(0.0, np.radians(4.0), t.size))
    r = flight_step_responses(t, {"x": u}, {"x": y})["x"]
    _, truth = signal.step(tf, T=r.t_s)
    want = response_metrics(r.t_s, np.interp(r.t_s - delay, r.t_s, truth, left=0.0))
    assert r.trusted_hz > 10.0, r.summary()
    assert r.metrics["rise_ms"] == pytest.approx(want["rise_ms"], rel=0.10), r.summary()
