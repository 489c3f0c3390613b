"""Simulated sensors: AttoPilot scaling and ADC, load cell, hall counter, timestamps."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from drivers.errors import DeviceError
from drivers.sim.rig import SimRig
from drivers.sim.sensor_params import SensorParams

QUIET = SensorParams(noise=False)
LSB_V = 20.0 / 2**16


def run(rig: SimRig, pulse: float, seconds: float, tick: float = 0.02):
    blocks = {k: [] for k in rig.sensors}
    for _ in range(round(seconds / tick)):
        rig.esc.set_pulse_us(pulse)
        rig.clock.sleep(tick)
        for k, s in rig.sensors.items():
            blocks[k].append(s.read_block())
    return {k: (np.concatenate([b.t_s for b in v]),
                {c: np.concatenate([b.values[c] for b in v]) for c in v[0].values})
            for k, v in blocks.items()}


def test_attopilot_scaling_and_quantisation():
    rig = SimRig(sensor_params=QUIET)
    rig.esc.arm()
    data = run(rig, 1700, 1.0)
    _, vals = data["power"]
    tr = rig.truth()
    assert vals["current_a"][-1] == pytest.approx(tr.current_bus_a, abs=LSB_V / 0.0366)
    assert vals["voltage_v"][-1] == pytest.approx(tr.voltage_bus_v, abs=LSB_V / 0.06369)
    codes = vals["current_a"] * 36.60e-3 / LSB_V  # ADC codes: whole numbers
    np.testing.assert_allclose(codes, np.round(codes), atol=1e-6)


def test_current_calibration_is_applied():
    """A rig file with the wrong scale reads proportionally wrong (36.60 vs 40 mV/A)."""
    right = SimRig(sensor_params=QUIET)
    wrong = SimRig(sensor_params=QUIET, power_cal={"current_mv_per_a": 40.0})
    readings = []
    for rig in (right, wrong):
        rig.esc.arm()
        readings.append(run(rig, 1700, 1.0)["power"][1]["current_a"][-1])
    assert readings[1] == pytest.approx(readings[0] * 36.60 / 40.0, rel=1e-3)


def test_current_sensor_is_unidirectional():
    """Regenerative braking (complementary) cannot show as negative current."""
    rig = SimRig(sensor_params=QUIET, esc_mode="complementary")
    rig.esc.arm()
    run(rig, 1800, 1.0)
    data = run(rig, 1520, 0.2, tick=0.0025)
    assert data["power"][1]["current_a"].min() >= 0.0


def test_load_cell_reads_thrust_after_tare_and_rings_at_its_frequency():
    rig = SimRig(sensor_params=QUIET)
    rest = run(rig, 1000, 0.2)["load_cell"][1]["thrust_n"]
    tare = rest.mean()
    assert tare == pytest.approx(QUIET.load_cell_offset_v * 10.0, abs=2e-3)  # offset 12 mV
    rig.esc.arm()
    data = run(rig, 1700, 1.5)["load_cell"][1]["thrust_n"]
    assert data[-1] - tare == pytest.approx(rig.truth().thrust_n, abs=3e-3)
    # mechanical 2nd-order: an impulse-like disturbance rings near load_cell_fn_hz
    acq = rig.acquisition
    from scipy import signal

    h = signal.dimpulse((acq.cell_b, acq.cell_a, 1 / QUIET.sample_rate_hz), n=4000)[1][0].ravel()
    spectrum = np.abs(np.fft.rfft(h))
    f = np.fft.rfftfreq(h.size, 1 / QUIET.sample_rate_hz)
    assert f[np.argmax(spectrum)] == pytest.approx(QUIET.load_cell_fn_hz, rel=0.1)


def test_load_cell_noise_level():
    rig = SimRig()
    thrust = run(rig, 1000, 1.0)["load_cell"][1]["thrust_n"]
    assert np.std(thrust) == pytest.approx(SensorParams().load_cell_noise_n, rel=0.1)


def test_hall_counter_measures_speed_from_magnet_periods():
    rig = SimRig(sensor_params=QUIET)
    rpm0 = run(rig, 1000, 0.2)["rpm"][1]["rpm"]
    assert np.all(rpm0 == 0.0)
    rig.esc.arm()
    rpm = run(rig, 1700, 1.5)["rpm"][1]["rpm"]
    assert rpm[-1] == pytest.approx(rig.truth().rpm, rel=2e-3)
    # values are 60 / (14 * whole counter ticks of 25 ns)
    ticks = 60.0 / (14 * rpm[rpm > 0] * 25e-9)
    np.testing.assert_allclose(ticks, np.round(ticks), atol=1e-3)
    # while the rotor coasts down every magnet period differs: one new value per magnet
    rig.esc.disarm()
    theta = [rig.plant.traj.sample(np.array([rig.clock.now()]), ("theta",))["theta"][0]]
    values = []
    for _ in range(25):
        rig.clock.sleep(0.02)
        values.append(rig.rpm.read_block().values["rpm"])
    theta.append(rig.plant.traj.sample(np.array([rig.clock.now()]), ("theta",))["theta"][0])
    passings = (theta[1] - theta[0]) * 14 / (2 * math.pi)
    assert np.count_nonzero(np.diff(np.concatenate(values))) == pytest.approx(passings, abs=2)


def test_rpm_falls_to_zero_when_the_rotor_stops():
    rig = SimRig(sensor_params=QUIET)
    rig.esc.arm()
    run(rig, 1600, 1.0)
    rig.esc.disarm()
    rpm = run(rig, 1000, 6.0)["rpm"][1]["rpm"]
    assert rpm[-1] == 0.0


def test_columns_share_the_sample_clock_and_jitter_is_bounded():
    rig = SimRig()
    rig.esc.arm()
    data = run(rig, 1600, 0.5)
    t_cell, t_pow, t_rpm = (data[k][0] for k in ("load_cell", "power", "rpm"))
    np.testing.assert_array_equal(t_cell, t_pow)
    np.testing.assert_array_equal(t_cell, t_rpm)
    nominal = np.arange(t_cell.size) / 25_000.0
    jitter = t_cell - nominal
    bound = math.sqrt(3) * SensorParams().jitter_s
    assert np.abs(jitter).max() <= bound + 1e-12
    assert np.std(jitter) == pytest.approx(SensorParams().jitter_s, rel=0.05)


def test_unread_sensor_overruns_its_buffer():
    rig = SimRig(sensor_params=replace(QUIET, buffer_s=1.0))
    rig.clock.sleep(1.5)
    with pytest.raises(DeviceError, match="overrun"):
        rig.power.read_block()
    block = rig.power.read_block()  # carries on from the oldest sample still buffered
    assert block.t_s[0] == pytest.approx(0.5, abs=1e-4)
