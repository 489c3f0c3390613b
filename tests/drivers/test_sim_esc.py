"""The simulated ESC: frame-sampled input, latency, failsafe, arming, stock filter."""

from __future__ import annotations

import numpy as np
import pytest

from drivers.sim.esc import EscSettings
from drivers.sim.plant import EscScheme
from drivers.sim.rig import SimRig
from drivers.sim.sensor_params import SensorParams

QUIET = SensorParams(noise=False)


def duty_trace(rig: SimRig) -> tuple[np.ndarray, np.ndarray]:
    traj = rig.plant.traj
    traj.flush()
    return traj.arrays["t"], traj.arrays["duty"]


def test_command_waits_for_the_next_frame_then_the_latency():
    rig = SimRig(sensor_params=QUIET, esc_settings=EscSettings(frame_rate_hz=100.0))
    rig.esc.arm()
    rig.esc.set_pulse_us(1500)
    rig.clock.sleep(0.2)
    rig.clock.sleep(0.0031)  # mid-frame: frames start every 10 ms
    t_cmd = rig.clock.now()
    rig.esc.set_pulse_us(1700)
    for _ in range(10):
        rig.esc.set_pulse_us(1700)
        rig.clock.sleep(0.01)
    t, duty = duty_trace(rig)
    first = t[np.argmax(duty > 0.6)]  # first integration point driven by the new duty
    frame_start = 0.21  # next frame boundary after t_cmd
    latency = rig.params.esc_latency_s
    assert t_cmd < frame_start
    # the new duty acts from frame_start + latency; the first point carrying it ends a substep
    assert frame_start + latency < first <= frame_start + latency + 0.01 + 1e-9


def test_disarmed_esc_ignores_pulses():
    rig = SimRig(sensor_params=QUIET)
    for _ in range(50):
        rig.esc.set_pulse_us(1800)
        rig.clock.sleep(0.01)
    tr = rig.truth()
    assert not tr.armed and tr.omega_rad_s == 0.0


def test_failsafe_drops_to_idle_when_commands_stop():
    rig = SimRig(sensor_params=QUIET, esc_settings=EscSettings(timeout_s=0.3))
    rig.esc.arm()
    for _ in range(50):
        rig.esc.set_pulse_us(1700)
        rig.clock.sleep(0.01)
    spinning = rig.truth().thrust_n
    rig.clock.sleep(0.25)  # host stalls, but not yet for timeout_s
    assert not rig.truth().failsafe
    rig.clock.sleep(0.1)
    tr = rig.truth()
    assert tr.failsafe and tr.failsafe_count == 1 and tr.duty == 0.0
    rig.clock.sleep(1.5)
    assert rig.truth().thrust_n < 0.1 * spinning  # motor coasted down at idle
    rig.esc.set_pulse_us(1700)  # commands resume: so does the ESC (VESC-like)
    rig.clock.sleep(0.05)
    assert not rig.truth().failsafe


def test_disarm_stops_driving_at_once():
    rig = SimRig(sensor_params=QUIET)
    rig.esc.arm()
    for _ in range(50):
        rig.esc.set_pulse_us(1700)
        rig.clock.sleep(0.01)
    rig.esc.disarm()
    rig.clock.sleep(0.05)
    tr = rig.truth()
    assert not tr.armed and tr.duty == 0.0 and tr.current_winding_a == 0.0


@pytest.mark.parametrize("scheme", list(EscScheme))
def test_stock_firmware_filters_the_input(scheme):
    rig = SimRig(sensor_params=QUIET, esc_mode=scheme)
    rig.esc.arm()
    for _ in range(40):
        rig.esc.set_pulse_us(1500)
        rig.clock.sleep(0.0025)
    for _ in range(40):
        rig.esc.set_pulse_us(1700)
        rig.clock.sleep(0.0025)
    _, duty = duty_trace(rig)
    levels = np.unique(np.round(duty[duty > 0], 6))
    if scheme is EscScheme.STOCK:
        assert len(levels) > 10  # duty creeps up frame by frame (low-pass)
    else:
        assert list(levels) == [0.5, 0.7]
