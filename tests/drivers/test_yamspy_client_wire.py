"""yamspy (an MSP client for Betaflight and INAV, PyPI 0.3.3) against the simulated FC, in a
process of its own as a flight controller's firmware is.

yamspy's ``MSPy`` opens the pty like a serial port and asks, at connect, API_VERSION,
FC_VARIANT, FC_VERSION, BUILD_INFO, BOARD_INFO, UID, ACC_TRIM, NAME, STATUS and STATUS_EX
(``MSPy.basic_info``); the simulator answers all of them, and refuses commands it does
not serve with ``$M!`` as Betaflight does.
"""

from __future__ import annotations

import math

import pytest

pytest.importorskip("serial")
yamspy = pytest.importorskip("yamspy")

from drivers.codecs import msp  # noqa: E402
from drivers.wire_sim.msp_fc import SimFlightController  # noqa: E402
from drivers.wire_sim.world_process import Constant, WorldProcess, one_device  # noqa: E402

G = 9.80665


@pytest.fixture
def board():
    world = WorldProcess(one_device, SimFlightController, {
        "imu": Constant(((0.0, 0.0, G), (math.radians(10), 0.0, 0.0), (0.0, 0.0, 0.0))),
        "acc_1g": 2048, "battery": Constant((12.34, 1.5))},
        name="sim-fc")  # in a process of its own, as the FC's firmware is
    sim = world.remote("device")
    with yamspy.MSPy(device=sim.get("path"), logfilename=None, loglevel="WARNING") as b:
        assert b != 1, "yamspy could not connect"
        yield sim, b
    world.close()


def _ask(b, name: str) -> dict:
    """yamspy's own request/receive/process; its data handler (code, error flags)."""
    assert b.send_RAW_msg(yamspy.MSPy.MSPCodes[name], data=[])
    handler = b.receive_msg()
    handler["result"] = b.process_recv_data(handler)  # < 0: yamspy saw an error
    return handler


def test_yamspy_identifies_the_simulated_fc(board):
    _, b = board
    cfg = b.CONFIG
    assert cfg["flightControllerIdentifier"] == "BTFL"
    assert cfg["apiVersion"] == "1.46.0"
    assert cfg["flightControllerVersion"] == "4.5.0"
    assert cfg["boardIdentifier"] == "SIMF" and cfg["targetName"] == "ROTORBENCH_SIM"
    assert cfg["armingDisableFlags"] == 0 and cfg["mode"] == 0  # STATUS_EX: disarmed
    assert cfg["buildInfo"] == "Nov 25 2026 12:00:00"
    assert cfg["uid"] == [0x524F544F, 0x5242454E, 1]
    assert cfg["accelerometerTrims"] == [0, 0] and cfg["name"] == "rotorbench sim"


def test_every_connect_time_request_is_served(board):
    """``MSPy.basic_info`` asks these at connect; none may get the '$M!' error reply."""
    sim, _ = board
    asked = {m.cmd for m in sim.get("requests") if isinstance(m, msp.Request)}
    connect = {msp.MSP_API_VERSION, msp.MSP_FC_VARIANT, msp.MSP_FC_VERSION, msp.MSP_BUILD_INFO,
               msp.MSP_BOARD_INFO, msp.MSP_UID, msp.MSP_ACC_TRIM, msp.MSP_NAME,
               msp.MSP_STATUS, msp.MSP_STATUS_EX}
    assert connect <= asked
    replies = msp.MspDecoder(typed=True).feed(b"".join(
        sim.handle(msp.encode_message(msp.Request(cmd))) for cmd in sorted(connect)))
    assert len(replies) == len(connect)
    assert not [r for r in replies if isinstance(r, msp.ErrorReply)]


@pytest.mark.parametrize("name", ["MSP_FC_VERSION", "MSP_BOARD_INFO", "MSP_STATUS_EX",
                                  "MSP_ANALOG", "MSP_RAW_IMU", "MSP_MOTOR"])
def test_yamspy_gets_a_reply(board, name):
    _, b = board
    reply = _ask(b, name)
    assert reply["code"] == yamspy.MSPy.MSPCodes[name] and reply["result"] >= 0
    assert not reply["crcError"] and not reply["packet_error"] and not reply["unsupported"]


def test_yamspy_reads_values_in_its_own_units(board):
    sim, b = board
    _ask(b, "MSP_ANALOG")
    assert b.ANALOG["voltage"] == pytest.approx(12.34) and b.ANALOG["amperage"] == 1.5
    _ask(b, "MSP_RAW_IMU")
    assert b.SENSOR_DATA["accelerometer"] == [0, 0, 2048]
    # Betaflight: the gyro's counts, 16.4 per deg/s (10 deg/s here)
    assert b.SENSOR_DATA["gyroscope"] == [164, 0, 0]
    sim.set("armed", True)
    _ask(b, "MSP_STATUS_EX")
    assert b.CONFIG["mode"] & 1  # the arming bit yamspy shows
    _ask(b, "MSP_MOTOR")
    assert b.MOTOR_DATA[:4] == [1000] * 4


def test_yamspy_is_told_when_a_command_is_not_served(board):
    _, b = board
    assert _ask(b, "MSP_PID")["unsupported"] == 1  # yamspy read the '$M!' error reply
    assert _ask(b, "MSP_FC_VERSION")["result"] >= 0  # and the next request still works
