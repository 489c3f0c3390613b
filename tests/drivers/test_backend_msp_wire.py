"""MSP flight-controller backend end to end against the simulated FC on a pseudo-terminal,
in a process of its own as a flight controller's firmware is."""

from __future__ import annotations

import math
import time

import numpy as np
import pytest

serial = pytest.importorskip("serial")

from drivers.backends.msp_fc import (  # noqa: E402
    NO_REPLY_LIMIT_S,
    MspClient,
    MspImu,
    MspMotorEsc,
    MspNoReply,
    MspRefused,
)
from drivers.backends.serial_link import open_port  # noqa: E402
from drivers.codecs import msp  # noqa: E402
from drivers.contracts import Esc, MonotonicClock, Sensor  # noqa: E402
from drivers.errors import DeviceError  # noqa: E402
from drivers.wire_sim.msp_fc import ClockImu, SimFlightController  # noqa: E402
from drivers.wire_sim.world_process import Constant, Remote, WorldProcess, one_device  # noqa: E402

G = msp.STANDARD_GRAVITY
IMU = Constant(((0.0, 0.0, G), (0.0, math.radians(90), 0.0), (math.radians(12.5), 0.0, math.pi)))


def flight_controller(**settings) -> tuple[WorldProcess, Remote]:
    """The simulated FC in its process, and the handle that reads and sets it."""
    world = WorldProcess(one_device, SimFlightController, settings, name="sim-fc")
    return world, world.remote("device")


@pytest.fixture
def fc():
    world, sim = flight_controller(imu=IMU, acc_1g=2048)
    port = open_port(sim.get("path"), 115200)
    client = MspClient(port, "fc")
    yield sim, client
    port.close()
    world.close()


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
    sim.set("armed", True)  # the FC was armed by the pilot: motor-test values do not apply
    esc.set_pulse_us(1500)
    assert sim.motors() == [1000] * 4
    sim.set("armed", False)
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


def test_a_lost_set_motor_reply_is_sent_again_and_counted():
    # an FC that applies the first SET_MOTOR but whose acknowledgement is lost
    world, sim = flight_controller(imu=IMU, acc_1g=2048, lost_acks=1)
    port = open_port(sim.get("path"), 115200)
    try:
        client = MspClient(port, "fc", timeout_s=1.0)
        esc = MspMotorEsc(client, 1, propellers_off=True)
        t0 = time.monotonic()
        esc.arm()  # its SET_MOTOR 1000 loses its reply: sent again after RESEND_AFTER_S
        assert time.monotonic() - t0 < 0.5  # not the whole timeout
        esc.set_pulse_us(1400)
        assert sim.get("lost") == 1 and sim.motors()[1] == 1400
        assert esc.link_errors() == {"resent": 1}
        sim.port.disconnect()  # gone: sent again, twice as late each time, until the timeout
        with pytest.raises(MspNoReply, match="no reply"):
            esc.set_pulse_us(1500)
        # after 0.05, 0.15, 0.35 and 0.75 s of the 1 s
        assert esc.link_errors() == {"resent": 1 + 4}
    finally:
        port.close()
        world.close()


def test_imu_poller_reports_a_silent_fc(fc):
    sim, client = fc
    dev = MspImu(client, rate_hz=100.0, acc_1g=2048)
    sim.port.disconnect()
    t_end = time.monotonic() + NO_REPLY_LIMIT_S + 2.0
    with pytest.raises(DeviceError, match=f"no reply.*none for {NO_REPLY_LIMIT_S:g} s"):
        while time.monotonic() < t_end:
            dev.read_block()
            time.sleep(0.05)
    assert dev.link_errors()["no_reply"] >= 1
    dev.close()


LATE_S = 0.25


def test_a_late_reply_is_counted_and_no_row_takes_it():
    """MSP replies carry no sequence number: a reply that comes after its request was given
    up on would be taken by a later request (stamped the delay too late), and each reply
    after it by the request after its own. The poll goes on, counts the miss, and no row
    kept holds any reply but its own.

    The FC holds its reply to the 20th RAW_IMU request ``LATE_S`` on the line (a
    USB-serial adapter's latency timer, a bridge's buffer) while it goes on answering, then
    sends it behind its next reply: the late reply comes after the client gave up, inside
    a later request (after that request's own reply) or waiting before the next one. Its
    acc x is its own clock (10 m/s^2 a second) when it read its IMU. It answers no
    MSP_MULTIPLE_MSP (as INAV), so the poll asks RAW_IMU alone, stamped by the host."""
    clock = MonotonicClock()  # the FC's and the rows' stamps
    world, sim = flight_controller(imu=ClockImu(clock), acc_1g=2048, multiple=False,
                                   late_reply=(20, LATE_S))
    port = open_port(sim.get("path"), 115200)
    client = MspClient(port, "fc")
    try:
        dev = MspImu(client, rate_hz=100.0, acc_1g=2048, attitude=False, clock=clock,
                     max_round_trip_s=0.05)
        time.sleep(0.2 + LATE_S + 0.5)
        block = dev.read_block()
        served = block.values["acc_x_m_s2"] / 10.0  # the FC's clock when it read its IMU
        late = served - block.t_s
        assert sim.get("raw_requests") > 40 and dev.link_errors()["no_reply"] == 1
        assert np.count_nonzero(block.t_s > 0.2 + LATE_S) > 20  # it went on
        # a row is served after it was sent (an LSB is 0.5 ms), and within its round trip
        assert late.min() > -0.002 and late.max() < 0.06, (late.min(), late.max())
        dev.close()
    finally:
        port.close()
        world.close()


def test_a_late_reply_handed_to_a_later_timed_request_is_passed_over_by_the_fc_clock():
    """The race no MSP client can see: the late reply comes inside a later request's round
    trip, ahead of that request's own reply, and is taken as its answer; the own reply
    comes 15 ms later, in a later packet (``late_ahead_s``). An FC that tells its clock
    served the late one before the last row: the poll passes it over and waits on for its
    request's own reply. So neither a row's stamp nor the clocks' offset (the largest
    ``send - served`` of the last rows) takes in the late reply (it would move the offset
    by ``LATE_S``), nor the own reply handed to the next request (served before that
    request was sent, it moved the offset by 4-9 ms)."""
    clock = MonotonicClock()
    world, sim = flight_controller(imu=ClockImu(clock), acc_1g=2048, rtc_clock=clock.now,
                                   late_reply=(20, LATE_S), late_ahead_s=0.015)
    port = open_port(sim.get("path"), 115200)
    try:
        client = MspClient(port, "fc")
        dev = MspImu(client, rate_hz=100.0, acc_1g=2048, attitude=False, clock=clock)
        time.sleep(0.2 + LATE_S + 0.5)
        block = dev.read_block()
        dropped = dev.slow_rows
        dev.close()
    finally:
        port.close()
        world.close()
    late = block.values["acc_x_m_s2"] / 10.0 - block.t_s  # reading time less the stamp
    assert late.min() > -2e-3 and late.max() < 0.016, (late.min(), late.max())
    assert dev.link_errors()["no_reply"] == 1 and dropped >= 1  # the row after the miss
    assert client.stale_replies == 1  # the late one, passed over
    assert np.count_nonzero(block.t_s > 0.2 + LATE_S) > 20  # it went on


@pytest.mark.parametrize("multiple", [True, False], ids=["betaflight", "inav"])
def test_rows_are_stamped_when_the_fc_read_its_imu_if_it_tells_its_clock(multiple):
    """With MSP_SET_RTC taken and MSP_RTC answered in the poll's MSP_MULTIPLE_MSP, a row's
    stamp is the FC's reading time to its clock's millisecond, however late the request
    reached it; an FC without MSP_MULTIPLE_MSP is stamped at the send time, the link's
    delay in it. The FC's requests reach it 0-15 ms late (a loaded host, a USB adapter's
    latency timer, a simulated FC's time scale): its acc x is its clock (10 m/s^2 a second)
    when it read its IMU, its MSP_RTC counts on the same clock."""
    clock = MonotonicClock()
    world, sim = flight_controller(imu=ClockImu(clock), acc_1g=2048, rtc_clock=clock.now,
                                   multiple=multiple, link_delay_s=0.015)
    port = open_port(sim.get("path"), 115200)
    try:
        dev = MspImu(MspClient(port, "fc"), rate_hz=50.0, acc_1g=2048, attitude=False,
                     clock=clock)
        time.sleep(1.5)
        block = dev.read_block()
        dev.close()
        fc_time = sim.rtc_s()  # set to the time of day, as radios' MSP scripts set it
    finally:
        port.close()
        world.close()
    late = block.values["acc_x_m_s2"] / 10.0 - block.t_s  # reading time less the stamp
    assert block.t_s.size > 40
    assert fc_time is not None and abs(fc_time - time.time()) < 2.0
    if multiple:
        # the link's 0-15 ms are not in the stamps: what is left is the FC's whole
        # milliseconds (one LSB of acc x is 0.5 ms of its clock) and the estimate of the
        # clocks' offset, the fastest request so far (taken as served at once: on a loaded
        # host the fastest of a few dozen took 1-2 ms, a bias the calibration's time offset
        # takes in, not jitter)
        spread = late[20:].max() - late[20:].min()
        assert spread < 3e-3, (late[20:].min(), late[20:].max())
        assert late.min() > -2e-3 and late.max() < 0.016
    else:  # the send time: the link's delay in each stamp
        assert late.max() - late.min() > 8e-3 and late.min() > -2e-3


def test_betaflight_needs_acc_scale(fc):
    _, client = fc
    with pytest.raises(DeviceError, match="acc_1g"):
        MspImu(client)


def test_identity_and_arming_state_are_read_and_an_armed_fc_is_refused(fc):
    sim, client = fc
    assert client.firmware() == {"variant": "BTFL", "msp_api": "1.46", "version": "4.5.0",
                                 "board": "SIMF (ROTORBENCH_SIM)"}
    assert client.armed() is False
    sim.set("armed", True)
    assert client.armed() is True
    esc = MspMotorEsc(client, 1, propellers_off=True)
    with pytest.raises(DeviceError, match="flight controller is armed"):
        esc.arm()
    assert not any(isinstance(m, msp.SetMotor) and m.values_us[1] != 1000
                   for m in sim.get("requests"))
    sim.set("armed", False)
    esc.arm()
    esc.set_pulse_us(1200)
    assert sim.motors()[1] == 1200
    esc.close()


def test_propellers_on_is_refused_because_the_fc_holds_the_last_value(fc):
    _, client = fc
    with pytest.raises(DeviceError, match="propellers-on run: Betaflight and INAV keep"):
        MspMotorEsc(client, 0)
