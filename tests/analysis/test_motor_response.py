"""In-flight motor response: a simulated motor with known rising and falling time
constants, dead time and map, driven by a flight-like command, is recovered."""

from __future__ import annotations

import numpy as np
import pytest

from analysis.motor_response import fit_motor_response

RATE = 2000.0


def _motor(seed: int, tau_up: float, tau_down: float, dead: float, seconds: float = 30.0):
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, seconds, 1.0 / RATE)
    # a hovering quad's command: a mean, slow drift and quick corrections
    u = 0.45 + 0.08 * np.sin(2 * np.pi * 0.3 * t)
    k = 0
    while k < t.size:
        n = int(rng.uniform(0.03, 0.3) * RATE)
        u[k:k + n] += rng.uniform(-0.15, 0.15)
        k += n
    u = np.clip(u, 0.1, 1.0)
    target = 2000 + 18000 * u + 6000 * u * u  # rpm, the static map
    lag = round(dead * RATE)
    target = np.concatenate((np.full(lag, target[0]), target[:-lag])) if lag else target
    w = np.empty(t.size)
    w[0] = target[0]
    for i in range(1, t.size):  # the asymmetric first order, exactly
        tau = tau_up if target[i - 1] > w[i - 1] else tau_down
        w[i] = target[i - 1] + (w[i - 1] - target[i - 1]) * np.exp(-1.0 / RATE / tau)
    return t, u, w + rng.normal(0.0, 60.0, t.size)


@pytest.mark.parametrize(("tau_up", "tau_down", "dead"), [(0.030, 0.045, 0.004),
                                                          (0.020, 0.020, 0.010)])
def test_the_time_constants_and_dead_time_of_a_known_motor(tau_up, tau_down, dead):
    t, u, w = _motor(3, tau_up, tau_down, dead)
    r = fit_motor_response(t, u, w)
    assert r.tau_up_s == pytest.approx(tau_up, rel=0.1), r.summary()
    assert r.tau_down_s == pytest.approx(tau_down, rel=0.1), r.summary()
    assert r.dead_time_s == pytest.approx(dead, abs=0.002)
    assert r.map_coefficients[1] == pytest.approx(18000, rel=0.1)


def test_a_slow_or_empty_log_says_why():
    t, u, w = _motor(3, 0.03, 0.04, 0.004, seconds=6.0)
    slow = fit_motor_response(t[::40], u[::40], w[::40])  # 50 Hz
    assert np.isnan(slow.tau_up_s) and "too slow" in slow.why
    empty = fit_motor_response(t[:50], u[:50], w[:50])
    assert "samples with command and speed" in empty.why


def test_holes_in_the_log_leave_the_time_constants():
    """A log with holes where a software-in-the-loop plant did not run (its clock jumped on
    while the motor stood still): the samples near them are left out, the rest still fit."""
    t, u, w = _motor(5, 0.030, 0.045, 0.004, seconds=20.0)
    jumps = np.searchsorted(t, np.arange(0.5, 19.5, 0.25))  # 76 holes of 40 ms
    shifted = t.copy()
    for j in jumps:
        shifted[j:] += 0.04
    r = fit_motor_response(shifted, u, w)
    assert r.tau_up_s == pytest.approx(0.030, rel=0.1), r.summary()
    assert r.tau_down_s == pytest.approx(0.045, rel=0.1), r.summary()
