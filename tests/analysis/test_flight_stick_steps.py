"""A log's rate steps read directly (analysis.stick_steps), also when the firmware's RC
smoothing rounds the stick step off."""

from __future__ import annotations

import math

import numpy as np
import pytest

from analysis.stick_steps import step_readings, step_rise_times, unit_step_figures


def _pt1(x: np.ndarray, dt: float, tau: float) -> np.ndarray:
    a = dt / (tau + dt)
    y = np.zeros_like(x)
    for k in range(1, x.size):
        y[k] = y[k - 1] + a * (x[k] - y[k - 1])
    return y


def _flight(smooth_tau_s: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Four +-100 deg/s steps of 0.25 s (and 0.35 s at zero), the setpoint through a PT3 of
    ``smooth_tau_s`` each (RC smoothing), the gyro a first-order lag of 15 ms on it."""
    dt = 1e-3
    t = np.arange(0.0, 3.0, dt)
    stick = np.zeros_like(t)
    for k, s in enumerate((1.0, -1.0, 1.0, -1.0)):
        stick[(t >= 0.3 + 0.6 * k) & (t < 0.55 + 0.6 * k)] = s * math.radians(100.0)
    sp = stick
    for _ in range(3 if smooth_tau_s > 0 else 0):
        sp = _pt1(sp, dt, smooth_tau_s)
    return t, sp, _pt1(sp, dt, 0.015)


@pytest.mark.parametrize("smooth_tau_s", [0.0, 0.006])
def test_every_step_is_read_sharp_or_smoothed(smooth_tau_s):
    t, sp, gyro = _flight(smooth_tau_s)
    got = step_readings(t, sp, gyro, min_step=math.radians(50.0))
    assert len(got) == 8  # each step and its return to zero
    # the gyro's own 10-90 % rise: the 15 ms lag's 33 ms, longer through the smoothing
    for rise, over in got:
        assert (rise > 0.030) and (rise < 0.060)
        assert over == pytest.approx(0.0, abs=0.5)
    assert step_rise_times(t, sp, gyro, min_step=math.radians(50.0)) == \
        [r for r, _ in got]


def test_a_sharp_steps_rise_is_the_lags():
    t, sp, gyro = _flight(0.0)
    rises = step_rise_times(t, sp, gyro, min_step=math.radians(50.0))
    assert np.median(rises) == pytest.approx(0.015 * math.log(9), rel=0.05)


def test_unit_step_figures():
    t = np.linspace(0.0, 1.0, 1001)
    z = 1.0 - np.exp(-t / 0.1) * np.cos(10 * t)
    rise, over = unit_step_figures(t, z)
    assert 0.0 < rise < 0.2
    assert over == pytest.approx(100 * float(np.max(z) - 1.0))


def _second_order(x: np.ndarray, dt: float, wn: float, zeta: float) -> np.ndarray:
    """A lightly damped loop's answer to ``x`` (semi-implicit Euler, fine at dt = 0.1 ms)."""
    y = np.zeros_like(x)
    v = 0.0
    for k in range(1, x.size):
        v += dt * wn * wn * (x[k - 1] - y[k - 1]) - dt * 2 * zeta * wn * v
        y[k] = y[k - 1] + dt * v
    return y


def test_a_return_step_read_while_the_gyro_still_swings_rises_as_the_step_out():
    """A rate loop with 45 % overshoot, its 0.25 s steps too short to settle: the return to
    zero starts from a gyro still swinging, and is read from its edge, not before it."""
    dt = 1e-4
    t = np.arange(0.0, 2.0, dt)
    sp = np.zeros_like(t)
    for k, s in enumerate((1.0, -1.0)):
        sp[(t >= 0.3 + 0.6 * k) & (t < 0.55 + 0.6 * k)] = s * math.radians(100.0)
    gyro = _second_order(sp, dt, wn=45.0, zeta=0.25)
    rises = step_rise_times(t, sp, gyro, min_step=math.radians(50.0))
    assert len(rises) == 4
    out, back = rises[0::2], rises[1::2]  # each step, then its return
    assert np.median(back) == pytest.approx(np.median(out), rel=0.05), rises
