"""Gyro noise against throttle: a rotor line that moves with throttle is found where the
motor speeds put it."""

from __future__ import annotations

import numpy as np
import pytest

from analysis.flight_noise import gyro_noise_vs_throttle


def test_a_rotor_line_moving_with_throttle_is_found_in_its_bin():
    rate = 2000.0
    t = np.arange(0.0, 60.0, 1.0 / rate)
    throttle = 0.2 + 0.6 * (t / t[-1])  # a slow climb through the throttle range
    rpm = 6000 + 20000 * throttle
    rotor_hz = rpm / 60.0
    phase = 2 * np.pi * np.cumsum(rotor_hz) / rate
    rng = np.random.default_rng(0)
    gyro = {"x": 0.05 * np.sin(2 * phase) + rng.normal(0, 0.01, t.size)}  # blade pass
    m = gyro_noise_vs_throttle(t, gyro, throttle, rpm)
    assert m is not None
    peaks = m.peaks("x", blades=2)
    assert len(peaks) >= 10
    for p in peaks:
        # the line is at the blade pass of the bin's speed, within the resolution (3.3 Hz)
        # and the speed's spread across the bin
        assert p["peak_hz"] == pytest.approx(p["blade_pass_hz"], abs=20.0), p
    assert m.windows.sum() > 300


def test_too_short_or_no_throttle_gives_none():
    t = np.arange(0.0, 0.1, 1 / 2000)
    assert gyro_noise_vs_throttle(t, {"x": np.zeros(t.size)}, np.zeros(t.size)) is None
    t = np.arange(0.0, 5, 1 / 2000)
    assert gyro_noise_vs_throttle(t, {"x": np.zeros(t.size)}, np.full(t.size, np.nan)) is None
