"""3DM-GX3-25 backend end to end against the simulated IMU on a pseudo-terminal, in a
process of its own as the IMU's firmware is."""

from __future__ import annotations

import sys
import time

import numpy as np
import pytest

pytest.importorskip("serial")

from drivers.backends.gx3_imu import Gx3Imu
from drivers.backends.serial_link import open_port
from drivers.codecs import gx3
from drivers.contracts import Sensor
from drivers.errors import DeviceError
from drivers.wire_sim.gx3 import SimGx3
from drivers.wire_sim.world_process import Constant, WorldProcess, one_device

ep = sys.modules["rotorbench_tests_expected_protocol"]


IMU = Constant(((0.0, 0.0, -gx3.STANDARD_GRAVITY), (0.01, 0.0, 0.0), (0.1, -0.05, 1.5)))


@pytest.fixture
def sim():
    """The simulated IMU in its process (a ``Remote``: ``sim.get("requests")`` reads it
    there)."""
    world = WorldProcess(one_device, SimGx3, {"imu": IMU, "period_s": 0.005}, name="sim-gx3")
    yield world.remote("device")
    world.close()


def test_continuous_stream_in_si(sim):
    port = open_port(sim.get("path"), gx3.BAUD)
    dev = Gx3Imu(port, packet=gx3.ACCEL_RATE)
    assert isinstance(dev, Sensor)
    assert sim.get("requests")[:2] == [gx3.stop_continuous(), gx3.set_continuous(gx3.ACCEL_RATE)]
    time.sleep(0.15)
    b = dev.read_block()
    assert len(b) > 10
    assert b.values["acc_z_m_s2"] == pytest.approx(np.full(len(b), -gx3.STANDARD_GRAVITY))
    assert b.values["gyro_x_rad_s"][0] == pytest.approx(0.01, rel=1e-6)
    spacing = np.diff(b.values["device_t_s"])
    assert np.all(spacing > 0)
    dev.close()
    time.sleep(0.05)
    assert sim.get("requests")[-1] == gx3.stop_continuous()
    assert sim.get("stream_cmd") is None
    port.close()


def test_euler_rates_packet(sim):
    port = open_port(sim.get("path"), gx3.BAUD)
    dev = Gx3Imu(port, packet=gx3.EULER_RATES)
    time.sleep(0.05)
    b = dev.read_block()
    assert b.values["yaw_rad"][-1] == pytest.approx(1.5)
    assert set(b.values) == {"roll_rad", "pitch_rad", "yaw_rad", "gyro_x_rad_s", "gyro_y_rad_s",
                             "gyro_z_rad_s", "device_t_s"}
    dev.close()
    port.close()


def test_silence_is_detected(sim):
    port = open_port(sim.get("path"), gx3.BAUD)
    dev = Gx3Imu(port, stale_s=0.1)
    sim.port.disconnect()
    time.sleep(0.2)
    with pytest.raises(DeviceError, match="no packet"):
        ep.wait_for(lambda: dev.read_block() is None)  # until the reader finds it silent
    dev.close()
    port.close()


def test_no_ack_is_reported(sim):
    sim.port.disconnect()
    port = open_port(sim.get("path"), gx3.BAUD)
    with pytest.raises(DeviceError, match="no continuous-mode ack"):
        Gx3Imu(port, open_timeout_s=0.1)
    port.close()
