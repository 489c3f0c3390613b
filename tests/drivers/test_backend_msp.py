"""MSP flight-controller backend end to end against the simulated FC on a pseudo-terminal."""

from __future__ import annotations

import math
import time

import pytest

serial = pytest.importorskip("serial")

from drivers.backends.msp_fc import (  # noqa: E402
    MspClient,
    MspImu,
    MspMotorEsc,
    MspNoReply,
    MspRefused,
)
from drivers.backends.serial_link import open_port  # noqa: E402
from drivers.codecs import msp  # noqa: E402
from drivers.contracts import Esc, Sensor  # noqa: E402
from drivers.errors import DeviceError  # noqa: E402
from drivers.wire_sim.msp_fc import SimFlightController  # noqa: E402

G = msp.STANDARD_GRAVITY


def imu(t):
    return ((0.0, 0.0, G), (0.0, math.radians(90), 0.0), (math.radians(12.5), 0.0, math.pi))


@pytest.fixture
def fc():
    sim = SimFlightController(imu, acc_1g=2048).start()
    port = open_port(sim.path, 115200)
    client = MspClient(port, "fc")
    yield sim, client
    port.close()
    sim.stop()


def test_imu_in_si_through_the_pty(fc):
    _, client = fc
    dev = MspImu(client, rate_hz=200.0, acc_1g=2048)
    assert isinstance(dev, Sensor) and dev.variant == "BTFL"
    time.sleep(0.15)
    b = dev.read_block()
    dev.close()
    assert len(b) >= 5
    assert b.values["acc_z_m_s2"][-1] == pytest.approx(G)
    assert b.values["gyro_y_rad_s"][-1] == pytest.approx(math.pi / 2)
    assert b.values["roll_rad"][-1] == pytest.approx(math.radians(12.5))
    assert b.values["yaw_rad"][-1] == pytest.approx(math.pi)
    assert b.t_s.size == b.values["roll_rad"].size


def test_motor_test_applies_only_while_disarmed(fc):
    sim, client = fc
    esc = MspMotorEsc(client, motor_index=2, propellers_off=True)
    assert isinstance(esc, Esc)
    esc.arm()
    esc.set_pulse_us(1350)
    assert sim.motors() == [1000, 1000, 1350, 1000]
    assert client.request(msp.Request(msp.MSP_MOTOR)).values_us[:4] == (1000, 1000, 1350, 1000)
    esc.set_pulse_us(5000)  # clamped to 2000
    assert sim.motors()[2] == 2000
    sim.armed = True  # the FC was armed by the pilot: motor-test values do not apply
    esc.set_pulse_us(1500)
    assert sim.motors() == [1000] * 4
    sim.armed = False
    esc.close()
    assert sim.motors() == [1000] * 4


def test_fc_refusal_and_silence_become_device_errors(fc):
    sim, client = fc
    with pytest.raises(MspRefused, match="refused MSP command 151"):
        client.request(msp.Request(151))
    sim.port.disconnect()
    t0 = time.monotonic()
    with pytest.raises(MspNoReply, match="no reply"):
        client.request(msp.Request(msp.MSP_ATTITUDE))
    assert time.monotonic() - t0 < 0.3
    esc = MspMotorEsc(client, 0, propellers_off=True)
    esc.disarm()  # never raises, even with the FC silent


def test_imu_poller_reports_a_silent_fc(fc):
    sim, client = fc
    dev = MspImu(client, rate_hz=100.0, acc_1g=2048)
    sim.port.disconnect()
    time.sleep(0.3)
    with pytest.raises(DeviceError, match="no reply"):
        dev.read_block()
    dev.close()


def test_betaflight_needs_acc_scale(fc):
    _, client = fc
    with pytest.raises(DeviceError, match="acc_1g"):
        MspImu(client)


def test_identity_and_arming_state_are_read_and_an_armed_fc_is_refused(fc):
    sim, client = fc
    assert client.firmware() == {"variant": "BTFL", "msp_api": "1.46", "version": "4.5.0",
                                 "board": "SIMF (ROTORBENCH_SIM)"}
    assert client.armed() is False
    sim.armed = True
    assert client.armed() is True
    esc = MspMotorEsc(client, 1, propellers_off=True)
    with pytest.raises(DeviceError, match="flight controller is armed"):
        esc.arm()
    assert not any(isinstance(m, msp.SetMotor) and m.values_us[1] != 1000
                   for m in sim.requests)
    sim.armed = False
    esc.arm()
    esc.set_pulse_us(1200)
    assert sim.motors()[1] == 1200
    esc.close()


def test_propellers_on_is_refused_because_the_fc_holds_the_last_value(fc):
    _, client = fc
    with pytest.raises(DeviceError, match="propellers-on run: Betaflight and INAV keep"):
        MspMotorEsc(client, 0)
