"""Every backend's bytes, in PyMeasure's ``expected_protocol`` style.

For a sequence of calls: the exact bytes the backend writes (hex written out here or taken
from ``fixtures/transcripts``, as protocols.md gives them), and what it makes of canned
replies. Serial and TCP backends run on ``expected_protocol.ScriptedPort``; the CAN
backends on a python-can ``virtual`` bus whose other end is the script. The NI-DAQmx
backend's calls into a mocked nidaqmx interpreter are checked in
``test_factory_nidaq.py`` and ``test_dead_host_ni.py``; the KISS telemetry backend's in
``test_backend_kiss_wire.py``.
"""

from __future__ import annotations

import itertools
import sys
import time
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("serial")

from drivers.backends.gx3_imu import Gx3Imu
from drivers.backends.loadcell_serial import LineLoadCell
from drivers.backends.msp_fc import MspClient, MspMotorEsc
from drivers.backends.vesc_uart import VescUartLink
from drivers.codecs import gx3, msp
from drivers.codecs import vesc_uart as vu
from drivers.codecs.loadcell_lines import TESTSTAND_V2
from drivers.codecs.transcript import parse_hex_dump
from drivers.errors import DeviceError

ep = sys.modules["rotorbench_tests_expected_protocol"]
T = Path(__file__).resolve().parents[2] / "fixtures" / "transcripts"
H = bytes.fromhex


def test_scripted_port_refuses_bytes_the_script_does_not_expect():
    port = ep.ScriptedPort([(H("01 02"), H("AA"))])
    port.write(H("01"))  # half a message: waits for the rest
    with pytest.raises(ep.ScriptMismatch, match="wrote 01 03"):
        port.write(H("03"))
    assert not port.done()


# -- MSP flight controller: identification and the motor test --------------------------------
def _msp(message) -> bytes:
    return msp.encode_message(message)  # a canned reply of the FC


def test_msp_identify_and_motor_test_bytes():
    set_motor_idle = H("24 4D 3C 10 D6" + " E8 03" * 8 + " C6")  # SET_MOTOR (214), all 1000
    port = ep.ScriptedPort([
        (H("24 4D 3C 00 02 02"), _msp(msp.FcVariant("BTFL"))),  # FC_VARIANT request (2)
        (H("24 4D 3C 00 01 01"), _msp(msp.ApiVersion(0, 1, 46))),  # API_VERSION (1)
        (H("24 4D 3C 00 96 96"), _msp(msp.StatusEx(125, 0, 0x23, 0, 0))),  # STATUS_EX (150)
        (set_motor_idle, _msp(msp.Ack(msp.MSP_SET_MOTOR))),  # arm(): every motor at 1000
        # set_pulse_us(1500) on motor 0: 1500 = DC 05, the rest 1000
        (H("24 4D 3C 10 D6 DC 05" + " E8 03" * 7 + " F4"), _msp(msp.Ack(msp.MSP_SET_MOTOR))),
        (set_motor_idle, _msp(msp.Ack(msp.MSP_SET_MOTOR))),  # disarm()
    ])
    client = MspClient(port, "serial://fc", timeout_s=0.2)
    assert client.identify() == ("BTFL", msp.ApiVersion(0, 1, 46))
    esc = MspMotorEsc(client, 0, url="serial://fc", propellers_off=True)
    esc.arm()
    esc.set_pulse_us(1500.0)
    esc.disarm()
    assert port.done() and not port.errors


def test_msp_refused_and_armed_replies():
    armed = msp.StatusEx(125, 0, 0x23, msp.ARMED_FLAG, 0)
    port = ep.ScriptedPort([(H("24 4D 3C 00 96 96"), _msp(armed))])
    esc = MspMotorEsc(MspClient(port, "serial://fc"), 0, url="serial://fc", propellers_off=True)
    with pytest.raises(DeviceError, match="serial://fc: the flight controller is armed"):
        esc.arm()
    port = ep.ScriptedPort([(H("24 4D 3C 00 02 02"), H("24 4D 21 00 02 02"))])  # $M! error
    with pytest.raises(DeviceError, match="FC refused MSP command 2"):
        MspClient(port, "serial://fc").identify()


# -- VESC over USB/UART --------------------------------------------------------------------------
def test_vesc_uart_get_values_and_commands():
    reply = parse_hex_dump((T / "vesc_uart" / "replies.hex").read_text())
    port = ep.ScriptedPort([
        (H("02 01 04 40 84 03"), reply),  # GET_VALUES (4): §3.4's example reply
        (H("02 05 05 00 00 C3 50 3A A5 03"), b""),  # SET_DUTY 0.5 (50000 = C3 50)
        (H("02 05 06 00 00 00 00 CD 85 03"), b""),  # SET_CURRENT 0 A (the stop)
    ])
    link = VescUartLink(port, "serial://vesc", timeout_s=0.2)
    v = link.values()
    assert (v.erpm, v.voltage_in_v, v.input_current_a) == pytest.approx((12000, 24.3, 3.1))
    link.send(vu.SetDuty(0.5))
    link.send(vu.SetCurrent(0.0))
    assert port.done()


# -- MicroStrain 3DM-GX3-25 ------------------------------------------------------------------------
def test_gx3_opens_the_stream_and_decodes_it():
    sample = gx3.EulerRates(125_000, 0.1, -0.05, 1.5, (0.01, 0.0, -0.02))
    port = ep.ScriptedPort([
        (H("FA 75 B4"), b""),  # stop any running stream (§2.2)
        (H("C4 C1 29 CF"), gx3.encode_reply(gx3.ContinuousAck(62_500, gx3.EULER_RATES))),
        (H("FA 75 B4"), b""),  # close(): the stream stops
    ])  # continuous 0xCF: the ack echoes the command
    dev = Gx3Imu(port, packet=gx3.EULER_RATES, stale_s=1.0, url="serial://gx3")
    port.send(gx3.encode_reply(sample))  # then the stream
    assert ep.wait_for(lambda: len(dev._rows) == 1)
    b = dev.read_block()
    assert b.values["roll_rad"][0] == pytest.approx(0.1, abs=1e-6)
    assert b.values["yaw_rad"][0] == pytest.approx(1.5, abs=1e-6)
    assert b.values["gyro_z_rad_s"][0] == pytest.approx(-0.02, abs=1e-6)
    assert b.values["device_t_s"][0] == pytest.approx(2.0)  # 125 000 ticks
    dev.close()
    assert port.done()


def test_gx3_without_ack_names_the_command():
    port = ep.ScriptedPort([(H("FA 75 B4"), b""), (H("C4 C1 29 CF"), b"")])
    with pytest.raises(DeviceError, match=r"no continuous-mode ack \(C4 .. CF\)"):
        Gx3Imu(port, packet=gx3.EULER_RATES, open_timeout_s=0.05, url="serial://gx3")


# -- line-printing load-cell board -------------------------------------------------------------
def test_loadcell_board_lines_to_si_and_the_backend_writes_nothing():
    text = (T / "loadcell" / "teststand_v2.txt").read_bytes()
    port = ep.ScriptedPort([(b"", text)])  # the board prints; the backend only listens
    dev = LineLoadCell(port, TESTSTAND_V2, stale_s=1.0)
    assert ep.wait_for(lambda: port.idle_reads > 0)  # all read, decoded and stored
    assert dev.decoder.stats.bytes_in == len(text)
    b = dev.read_block()
    assert len(b) >= 1 and np.all(np.isfinite(b.values["thrust_n"]))
    assert dev.decoder.stats.malformed == 0
    assert port.written == b"" and port.done()
    dev.close()


# -- VESC and DroneCAN on CAN --------------------------------------------------------------------
can = pytest.importorskip("can")
_channels = itertools.count()


@pytest.fixture
def bus_pair():
    from drivers.backends.can_link import CanLink

    name = f"transcript-{next(_channels)}"
    host_bus = can.Bus(interface="virtual", channel=name)
    dev_bus = can.Bus(interface="virtual", channel=name)
    link = CanLink(host_bus, "host")
    yield link, dev_bus
    link.close()
    host_bus.shutdown()
    dev_bus.shutdown()


def _frames(dev_bus, n: int, timeout_s: float = 1.0) -> list:
    out = []
    while len(out) < n:
        msg = dev_bus.recv(timeout_s)
        if msg is None:
            break
        out.append(msg)
    return out


def _send_log(dev_bus, path: Path) -> None:
    for line in path.read_text().splitlines():
        ident, data = line.split()[2].split("#")
        dev_bus.send(can.Message(arbitration_id=int(ident, 16), data=bytes.fromhex(data),
                                 is_extended_id=True))


def test_vesc_can_duty_and_stop_frames_and_status_values(bus_pair):
    from drivers.backends.vesc import VescEsc, VescEscSettings, VescTelemetry

    link, dev_bus = bus_pair
    esc = VescEsc(link, VescEscSettings(1, keepalive_s=0.9, host_timeout_s=5.0))
    tel = VescTelemetry(link, 1, 7, stale_s=1.0)
    esc.arm()
    esc.set_pulse_us(1250.0)  # duty 0.25
    esc.disarm()
    sent = [(m.arbitration_id, bytes(m.data).hex().upper()) for m in _frames(dev_bus, 3)]
    # §3.2 / vesc/examples.log: SET_DUTY 0.25 = id 0x001, 000061A8; SET_CURRENT 0 = id 0x101
    assert (0x001, "000061A8") in sent
    assert sent[-1] == (0x101, "00000000")
    assert {i for i, _ in sent} <= {0x001, 0x101}
    for _ in range(2):  # a row per STATUS 1, with the latest STATUS 4 and 5 values
        _send_log(dev_bus, T / "vesc" / "examples.log")  # the statuses of controller 1
    time.sleep(0.1)
    b = tel.read_block()
    assert len(b) == 2
    assert b.values["rpm"][-1] == pytest.approx(12000 / 7)  # 12000 ERPM, 7 pole pairs
    assert b.values["voltage_v"][-1] == pytest.approx(24.3)
    assert b.values["current_a"][-1] == pytest.approx(3.1)
    assert np.isnan(b.values["voltage_v"][0])  # before the first STATUS 5
    esc.close()
    tel.close()


def test_dronecan_raw_command_frames_and_status_values(bus_pair):
    from drivers.backends.dronecan_esc import (
        DroneCanEsc,
        DroneCanEscSettings,
        DroneCanEscTelemetry,
    )
    from drivers.codecs import dronecan as dc
    from drivers.codecs.can_log import CanFrame

    link, dev_bus = bus_pair
    tel = DroneCanEscTelemetry(link, 2, stale_s=1.0)
    _send_log(dev_bus, T / "dronecan" / "examples.log")  # §4.2: a Status of ESC 2
    time.sleep(0.1)
    b = tel.read_block()
    assert b.values["rpm"][-1] == pytest.approx(12000)
    assert b.values["voltage_v"][-1] == pytest.approx(16.0)
    assert b.values["current_a"][-1] == pytest.approx(12.5)
    tel.close()
    _frames(dev_bus, 10, timeout_s=0.05)  # drop the log's own frames echoed by the bus
    esc = DroneCanEsc(link, DroneCanEscSettings(2, node_id=100, period_s=0.02,
                                                host_timeout_s=5.0))
    esc.arm()
    esc.set_pulse_us(2000.0)
    time.sleep(0.1)
    esc.close()
    dec = dc.DroneCanDecoder()
    cmds = []
    for m in _frames(dev_bus, 50, timeout_s=0.05):
        for r in dec.feed(CanFrame(m.arbitration_id, bytes(m.data), True, m.timestamp)):
            if isinstance(r.message, dc.RawCommand):
                assert dc.MessageId.from_int(m.arbitration_id).source_node_id == 100
                cmds.append(r.message.cmd)
    assert any(c[2] == dc.RAW_MAX for c in cmds)  # full throttle in slot 2 (8191)
    assert cmds[-1][2] == 0  # the stop


# -- PI GCS hexapod over TCP (the backend's wire layer) ---------------------------------------
def test_pi_gcs_commands_error_checks_and_queries():
    from drivers.backends.pi_hexapod import _Link
    from drivers.codecs import gcs

    sock = ep.ScriptedPort([
        (b"MOV X 1 Y 0.5\n", b""),  # a command has no reply ...
        (b"ERR?\n", b"0\n"),  # ... so ERR? follows it (pipython's default)
        (b"POS?\n", b"X=1.0000 \nY=0.5000 \nZ=0.0000 \nU=0.0000 \nV=0.0000 \nW=0.0000\n"),
        (b"ERR?\n", b"10\n"),  # after a stop: error 10
    ])
    link = _Link(sock, "tcp://hexapod", timeout_s=0.5)
    link.send(gcs.mov({"X": 1.0, "Y": 0.5}))
    link.check("MOV")
    link.send(gcs.pos_query())
    pos = gcs.parse_axis_values(link.reply())
    assert pos == {"X": 1.0, "Y": 0.5, "Z": 0.0, "U": 0.0, "V": 0.0, "W": 0.0}
    with pytest.raises(DeviceError, match=r"'WGO' failed: GCS error 10 \(stopped by command"):
        link.check("WGO")
    assert sock.done()
    link.close()
    assert sock.closed
