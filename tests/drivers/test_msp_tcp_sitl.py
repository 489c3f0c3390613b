"""msp+tcp:// against the real firmware: Betaflight 4.6.0 SITL in a network namespace.

Each test starts its own SITL (``tests/sitl.py``): identity through the rig URL, the motor
test through the ESC role, RAW_IMU through the IMU role with the firmware fed a known FDM
stream, the refusal of a motor test while armed, and the transport that never lets a
byte outside an MSP frame reach a firmware that exits on a stray ``'R'``.
"""

from __future__ import annotations

import math
import socket
import statistics
import sys
import time
from pathlib import Path
from types import SimpleNamespace

import pytest
from rotorbench_tests_sitl import Fdm, Rc, start_sitl

from bench.rig.rig import load_rig
from drivers.codecs import msp
from drivers.codecs.sitl import FDM_PORT, MSP_PORT, RC_PORT
from drivers.contracts import MonotonicClock
from drivers.device_context import DeviceContext
from drivers.device_options import parse_device
from drivers.errors import DeviceError
from drivers.factory import open_rig

pytestmark = pytest.mark.slow(wall_s=15)

factory_rigs = sys.modules["rotorbench_tests_factory_rigs"]  # factory_rigs.py, by conftest

RIGS = Path(__file__).resolve().parents[2] / "bench" / "data" / "rigs"
URL = f"msp+tcp://127.0.0.1:{MSP_PORT}"
G = msp.STANDARD_GRAVITY
SITL_ACC_1G = 256  # the virtual accelerometer's acc_1G: RAW_IMU acc counts per g
SITL_GYRO_LSB_PER_DPS = 16.4  # what the SITL packs per deg/s; RAW_IMU sends it unscaled


@pytest.fixture
def rig_file(tmp_path):
    """sim-serial.toml's stand with the ESC role on the SITL's motor 1 over TCP (the
    sensors stay the simulated serial board, on a pty)."""
    body = f'url = "{URL}"\noptions = {{ motor = 0, timeout_s = 2.0, propellers_off = true }}'
    return load_rig(factory_rigs.write(tmp_path, {"esc": body}, RIGS / "sim-serial.toml"))


def test_two_instances_on_the_same_ports_never_meet(sitl, rig_file, tmp_path):
    other = start_sitl(tmp_path / "other")
    try:
        with sitl.inside():
            rig = open_rig(rig_file)
        with other.inside():
            rig2 = open_rig(rig_file)
        with rig, rig2:
            rig.esc.arm()
            rig.esc.set_pulse_us(1300)
            assert _motors(rig.esc.client, (1300, 1000, 1000, 1000))[0] == 1300
            assert _motors(rig2.esc.client, (1000,) * 4) == (1000,) * 4
    finally:
        other.stop()


def _imu(tmp_path, url=URL, **options):
    """The IMU role opened through the registry (an IMU-bench rig would need a hexapod);
    call inside the SITL's namespace. Returns the context (to close) and the sensor."""
    rig = SimpleNamespace(path=tmp_path / "sitl-imu.toml",
                          imu=SimpleNamespace(value=lambda key: 50.0))
    dev = SimpleNamespace(url=url, options={"acc_1g": SITL_ACC_1G, "timeout_s": 2.0,
                                            **options})
    spec = parse_device(rig.path, "imu", dev)
    ctx = DeviceContext(rig, MonotonicClock(), {"imu": spec})
    try:
        return ctx, ctx.open(spec)
    except BaseException:
        ctx.close()
        raise


def _status(client) -> msp.StatusEx:
    reply = client.request(msp.Request(msp.MSP_STATUS_EX))
    assert isinstance(reply, msp.StatusEx)
    return reply


def _rows(imu, n: int, timeout_s: float):
    """The first block of at least ``n`` rows the IMU role gives within ``timeout_s`` (its
    poller runs at 50 Hz; a loaded host may starve it for a while)."""
    deadline = time.monotonic() + timeout_s
    while True:
        time.sleep(0.1)
        block = imu.read_block()
        if len(block) >= n or time.monotonic() > deadline:
            return block


def test_identity_through_the_rig_url(sitl, rig_file):
    with sitl.inside():
        rig = open_rig(rig_file)
    with rig:
        assert rig.context.answers["esc"] == "flight controller BTFL, MSP API 1.47, motor 0"
        fw = rig.esc.client.firmware()
        assert (fw["variant"], fw["msp_api"], fw["version"]) == ("BTFL", "1.47", "4.6.0")
        assert fw["board"].startswith("SITL")
        t = []
        for _ in range(20):
            t0 = time.monotonic()
            rig.esc.client.request(msp.Request(msp.MSP_API_VERSION))
            t.append(time.monotonic() - t0)
        print(f"SITL up in {sitl.started_s:.2f} s; MSP round trip median "
              f"{statistics.median(t) * 1e3:.1f} ms, max {max(t) * 1e3:.1f} ms")
        assert statistics.median(t) < 0.1


def test_motor_test_through_the_esc_role(sitl, rig_file):
    with sitl.inside():
        rig = open_rig(rig_file)
    with rig:
        esc, client = rig.esc, rig.esc.client
        esc.arm()
        esc.set_pulse_us(1300)
        # MSP_MOTOR reads the mixer's output, which takes the motor-test value on the
        # firmware's next control-loop run after the serial task stored it
        assert _motors(client, (1300, 1000, 1000, 1000)) == (1300, 1000, 1000, 1000)
        esc.disarm()
        assert _motors(client, (1000,) * 4) == (1000,) * 4
    assert sitl.alive()


def _motors(client, want: tuple[int, ...], timeout_s: float = 2.0) -> tuple[int, ...]:
    """MSP_MOTOR's first four values once they are ``want``, else the last read."""
    deadline = time.monotonic() + timeout_s
    while True:
        got = tuple(client.request(msp.Request(msp.MSP_MOTOR)).values_us[:4])
        if got == want or time.monotonic() > deadline:
            return got
        time.sleep(0.02)


def test_raw_imu_through_the_imu_role_with_the_scaling_checked(sitl, tmp_path):
    # FRD body rates p, q, r (rad/s) and a specific force (FLU, m/s²) fed at 200 Hz;
    # p = 10 rad/s (573 deg/s) tells 16.4 from 16.384 counts per deg/s by 9 counts
    fdm = Fdm(gyro_frd_rad_s=(10.0, 0.5, -0.25), specific_force_flu_m_s2=(1.0, -2.0, G))
    feed = sitl.feed(FDM_PORT, fdm.packet, 200.0)
    with sitl.inside():
        ctx, imu = _imu(tmp_path)  # the role's default scaling for Betaflight
    want_acc = (1.0 * 256 / G, -2.0 * 256 / G, 256)  # counts; the FC low-passes them
    try:
        # the acc low-pass settles in firmware time, which a loaded host slows: read until
        # it has (0.6 s when quiet), then judge the last reading
        deadline = time.monotonic() + 5.0
        while True:
            time.sleep(0.2)
            raw = imu.imu.client.request(msp.Request(msp.MSP_RAW_IMU))
            if time.monotonic() > deadline or all(
                    abs(r - w) <= 1.0 for r, w in zip(raw.acc, want_acc, strict=True)):
                break
        imu.read_block()
        block = _rows(imu, 5, 5.0)
    finally:
        imu.close()
        ctx.close()
    assert feed.sent >= 50  # the stream flowed (a loaded host sends fewer than 200 a second)
    # the wire: gyro (p, -q, -r) x 180/pi x 16.4 truncated; acc = specific force x 256/g
    want_gyro = [math.degrees(w) * SITL_GYRO_LSB_PER_DPS for w in (10.0, -0.5, 0.25)]
    assert all(abs(r - w) <= 1.0 for r, w in zip(raw.gyro, want_gyro, strict=True)), raw
    assert all(abs(r - w) <= 1.0 for r, w in zip(raw.acc, want_acc, strict=True)), raw
    # the role: SI in the FC's body axes (forward-left-up)
    assert len(block) >= 5
    lsb = math.radians(1.0 / SITL_GYRO_LSB_PER_DPS)
    for name, want in (("imu_gyro_x_rad_s", 10.0), ("imu_gyro_y_rad_s", -0.5),
                       ("imu_gyro_z_rad_s", 0.25)):
        assert block.values[name] == pytest.approx(want, abs=1.5 * lsb), name
    count = G / SITL_ACC_1G
    for name, want in (("imu_acc_x_m_s2", 1.0), ("imu_acc_y_m_s2", -2.0),
                       ("imu_acc_z_m_s2", G)):
        assert block.values[name] == pytest.approx(want, abs=count), name



def _wait(what, check, timeout_s):
    end = time.monotonic() + timeout_s
    while time.monotonic() < end:
        if check():
            return
        time.sleep(0.05)
    pytest.fail(f"{what} not within {timeout_s:g} s")


def test_the_bench_refuses_a_motor_test_while_the_fc_is_armed(sitl, rig_file):
    sitl.feed(FDM_PORT, Fdm().packet, 200.0)  # attitude established: no ANGLE flag
    rc = Rc()
    sitl.feed(RC_PORT, rc.packet, 100.0)
    with sitl.inside():
        rig = open_rig(rig_file)
    with rig:
        esc, client = rig.esc, rig.esc.client
        # ARM on AUX1, steps 32..48 (1700..2100 us): index 0, box 0, aux 0, start, end
        client.request(msp.Unknown(msp.REQUEST, 35, bytes([0, 0, 0, 32, 48, 0, 0]).hex()))
        _wait("arming allowed (boot grace, RC, FDM)",
              lambda: _status(client).arming_disable_flags == 0, 10.0)
        esc.arm()  # disarmed FC: the motor test may start
        rc.channels[4] = 2000
        _wait("armed", lambda: _status(client).armed, 3.0)
        with pytest.raises(DeviceError, match="flight controller is armed"):
            esc.arm()
        rc.channels[4] = 1000
        _wait("disarmed", lambda: not _status(client).armed, 3.0)


def test_the_tcp_port_never_sends_a_byte_outside_an_msp_frame(sitl, rig_file):
    with sitl.inside():
        rig = open_rig(rig_file)
    with rig:
        port, client = rig.esc.client.port, rig.esc.client
        frame = msp.request(msp.MSP_API_VERSION)
        for bad in (b"R", b"#", b"\x02", frame + b"R", b"R" + frame, frame[:-1],
                    frame[:-1] + bytes([frame[-1] ^ 1]), msp.encode_v1(msp.REPLY, 1, b"\1\1\1")):
            with pytest.raises(DeviceError, match="not whole MSP requests"):
                port.write(bad)
        assert client.identify()[0] == "BTFL"  # nothing reached the firmware
        assert port.write(frame + msp.request(msp.MSP_FC_VARIANT, version=2)) > 0
    # the hazard is real: the same byte on a plain socket ends the firmware
    with sitl.inside():
        raw = socket.create_connection(("127.0.0.1", MSP_PORT), 2.0)
    with raw:
        raw.sendall(b"R")
        _wait("the SITL exits on a stray 'R'", lambda: not sitl.alive(), 3.0)


def test_a_second_client_and_a_closed_port_are_one_line_errors(sitl, rig_file, tmp_path):
    with sitl.inside():
        rig = open_rig(rig_file)
        # Betaflight serves one client per port: it closes a second at once, which the
        # client sees as the end of the stream or, writing first, as a reset
        with rig, pytest.raises(DeviceError, match=r"closed by the peer|reset by peer"):
            _imu(tmp_path)
        with pytest.raises(DeviceError, match=r"cannot connect to 127\.0\.0\.1:5762 "
                                              r"\(Connection refused\)"):
            _imu(tmp_path, "msp+tcp://127.0.0.1:5762")  # UART2 has no function: no listener
