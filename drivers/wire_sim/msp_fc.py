"""A simulated Betaflight-like flight controller answering MSP on a pseudo-terminal.

Answers (protocols.md §1): API_VERSION, FC_VARIANT ("BTFL"), FC_VERSION, BOARD_INFO,
BUILD_INFO, UID, ACC_TRIM, NAME (what yamspy's ``MSPy.basic_info`` asks at connect),
STATUS and STATUS_EX (bit 0 of the flight-mode flags set while ``armed``), SET_RTC and RTC
(the FC's clock: set to the host's time, then counting on ``rtc_clock``), MULTIPLE_MSP (one
size-prefixed part per command, in one reply; ``multiple=False``: refused, as INAV does),
ANALOG (from
``battery() -> (V, A)``), RAW_IMU (acc in counts with ``acc_1g``; gyro in counts,
``gyro_lsb_per_dps``: Betaflight's 16.4, or 1 for INAV's whole deg/s), ATTITUDE (0.1°
roll/pitch, whole-degree yaw, §1.5), MOTOR, SET_MOTOR (ack; values apply only while
disarmed, and a payload shorter than ``motor_count`` motors is refused, §1.7); anything
else gets the error reply ``$M!`` as Betaflight sends for a command it does not know.
Like Betaflight and INAV, the motor-test values have no expiry: when the host stops
sending, the motors keep the last value (docs/protocols.md, dead host).
The IMU values come from ``imu(t_s) -> (acc_m_s2, gyro_rad_s, (roll, pitch, yaw) rad)``.
Faults of the line, for the backend's tests (values, so they cross to a device process):
``lost_acks`` (the first SET_MOTOR acknowledgements lost, the values applied),
``late_reply`` (one RAW_IMU reply held on the line while the FC goes on answering) and
``link_delay_s`` (each request reaches the FC up to that late).
"""

from __future__ import annotations

import math
import random
import struct
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

from drivers.codecs import msp
from drivers.wire_sim.pty_port import PtyDevice
from drivers.wire_sim.pty_sim import PtySimulator

if TYPE_CHECKING:  # not imported here: numpy's import time at each device process's start
    from drivers.contracts import MonotonicClock

Vec3 = tuple[float, float, float]
ImuModel = Callable[[float], tuple[Vec3, Vec3, Vec3]]


def _i16(x: float) -> int:
    return max(-(2**15), min(2**15 - 1, round(x)))


@dataclass(frozen=True)
class ClockImu:
    """A stand-in IMU (an ``ImuModel``) at rest, level, whose acc x reads ``clock``
    (``acc_x_per_s`` m/s^2 a second): a row tells when the FC read its IMU. A value, so it
    crosses to a device process pickled, where a lambda cannot; a ``MonotonicClock`` reads
    the same there as in the host (one monotonic clock per machine)."""

    clock: MonotonicClock
    acc_x_per_s: float = 10.0

    def __call__(self, _t: float) -> tuple[Vec3, Vec3, Vec3]:
        return ((self.acc_x_per_s * self.clock.now(), 0.0, msp.STANDARD_GRAVITY),
                (0.0, 0.0, 0.0), (0.0, 0.0, 0.0))


def _asks_imu(m: msp.MspMessage) -> bool:
    """A request for RAW_IMU, alone or first in an MSP_MULTIPLE_MSP."""
    if isinstance(m, msp.Request):
        return m.cmd == msp.MSP_RAW_IMU
    return (isinstance(m, msp.Unknown) and m.direction == msp.REQUEST
            and m.cmd == msp.MSP_MULTIPLE_MSP and m.payload_hex[:2] == f"{msp.MSP_RAW_IMU:02x}")


class SimFlightController(PtySimulator):
    """MSP responder; ``armed`` switches SET_MOTOR off like the real firmware."""

    def __init__(self, imu: ImuModel, *, acc_1g: int = 2048,
                 gyro_lsb_per_dps: float = msp.BTFL_GYRO_LSB_PER_DPS, motor_count: int = 4,
                 api: tuple[int, int] = (1, 46), version: tuple[int, int, int] = (4, 5, 0),
                 battery: Callable[[], tuple[float, float]] = lambda: (0.0, 0.0),
                 rtc_clock: Callable[[], float] | None = None, multiple: bool = True,
                 lost_acks: int = 0, late_reply: tuple[int, float] | None = None,
                 late_ahead_s: float | None = None, link_delay_s: float = 0.0) -> None:
        """``lost_acks``: the first that many SET_MOTOR acknowledgements are lost (the values
        apply; ``lost`` counts them). ``late_reply=(n, delay_s)``: the reply to the n-th
        request for RAW_IMU, alone or in MSP_MULTIPLE_MSP (``raw_requests`` counts them), is
        held ``delay_s`` on the line (a USB-serial adapter's latency timer, a bridge's
        buffer) while the FC goes on answering, then sent right behind its next reply
        (inside a later request, after that request's own reply, however the host and this
        process are scheduled), or right ahead of it with ``late_ahead_s``, that request's own
        reply following that many seconds later (the race no MSP client can see: the later
        request is handed the late reply, its own comes in a later packet of a USB
        adapter's, and the request after it would be handed that). ``link_delay_s``:
        each chunk of requests reaches the FC 0 to that many seconds late (uniform, seeded:
        a loaded host, an adapter's latency timer)."""
        self.imu = imu
        self.version = version  # what this simulator reports; not a claim about a firmware
        self.battery = battery
        self.acc_1g = acc_1g
        self.gyro_lsb_per_dps = gyro_lsb_per_dps
        self.motor_count = motor_count
        self.api = api  # what this simulator reports; not a claim about a real firmware
        self.armed = False
        self.craft_name = "rotorbench sim"
        self.motor_disarmed = [msp.MOTOR_MIN_US] * motor_count
        self.requests: list[msp.MspMessage] = []
        self._decoder = msp.MspDecoder(typed=True)
        self._t0 = time.monotonic()
        # the FC's millisecond timer (a simulated world's: its clock, paced as it is)
        self.rtc_clock = rtc_clock or (lambda: time.monotonic() - self._t0)
        self.multiple = multiple
        self._rtc_offset_s: float | None = None  # the time MSP_SET_RTC set, less rtc_clock's
        self._lock = threading.Lock()
        self.lost_acks = lost_acks
        self.lost = 0
        self.late_reply = late_reply
        self.late_ahead_s = late_ahead_s
        self.raw_requests = 0
        self._held: tuple[float, bytes] | None = None  # a late reply: when due, its bytes
        self.link_delay_s = link_delay_s
        self._link_rng = random.Random(3)
        self.port = PtyDevice(self.handle)

    def motors(self) -> list[int]:
        """What the motors get now: motor-test values only while disarmed (§1.7)."""
        with self._lock:
            return list(self.motor_disarmed) if not self.armed else \
                [msp.MOTOR_MIN_US] * self.motor_count

    def handle(self, data: bytes) -> bytes:
        if self.link_delay_s:
            time.sleep(self._link_rng.uniform(0.0, self.link_delay_s))
        out = bytearray()
        for m in self._decoder.feed(data):
            self.requests.append(m)
            reply = self._reply(m)
            if isinstance(m, msp.SetMotor) and self.lost < self.lost_acks:
                self.lost += 1
                continue  # applied, the acknowledgement lost
            if _asks_imu(m):
                self.raw_requests += 1
                if self.late_reply is not None and self.raw_requests == self.late_reply[0]:
                    self._held = (time.monotonic() + self.late_reply[1], reply)
                    continue
            out += reply
        if out and self._held is not None and time.monotonic() >= self._held[0]:
            held, self._held = self._held[1], None
            if self.late_ahead_s is None:
                out += held  # behind the reply it waited for
            else:  # ahead of it, the reply itself in a later packet
                self.port.write(held)
                time.sleep(self.late_ahead_s)
        return bytes(out)

    def _reply(self, m: msp.MspMessage) -> bytes:
        enc = msp.encode_message
        if isinstance(m, msp.SetMotor):
            if len(m.values_us) < self.motor_count:
                return enc(msp.ErrorReply(msp.MSP_SET_MOTOR))
            with self._lock:
                self.motor_disarmed = list(m.values_us[: self.motor_count])
            return enc(msp.Ack(msp.MSP_SET_MOTOR))
        if isinstance(m, msp.Unknown) and m.direction == msp.REQUEST:
            return self._reply_with_payload(m.cmd, bytes.fromhex(m.payload_hex))
        if not isinstance(m, msp.Request):
            return b""
        cmd = m.cmd
        if cmd == msp.MSP_API_VERSION:
            return enc(msp.ApiVersion(0, *self.api))
        if cmd == msp.MSP_FC_VARIANT:
            return enc(msp.FcVariant("BTFL"))
        flags = msp.ARMED_FLAG if self.armed else 0
        if cmd == msp.MSP_STATUS:
            return enc(msp.FcStatus(125, 0, 0b100001, flags, 0))  # acc + gyro present (§1.8)
        if cmd == msp.MSP_STATUS_EX:
            # rest: config state 0, CPU temperature 0 degC, 4 control-rate profiles (§1.8)
            return enc(msp.StatusEx(125, 0, 0b100001, flags, 0, system_load=5,
                                    profile_count=4, rest_hex="00" "0000" "04"))
        if cmd == msp.MSP_FC_VERSION:
            return enc(msp.FcVersion(*self.version))
        if cmd == msp.MSP_BOARD_INFO:
            return enc(msp.BoardInfo("SIMF", target_name="ROTORBENCH_SIM",
                                     board_name="simulated FC", manufacturer_id="RTRB"))
        if cmd == msp.MSP_BUILD_INFO:
            return enc(msp.BuildInfo("Nov 25 2026", "12:00:00", "0000000"))
        if cmd == msp.MSP_UID:
            return enc(msp.Uid((0x524F544F, 0x5242454E, 0x00000001)))  # "ROTO" "RBEN" 1
        if cmd == msp.MSP_ACC_TRIM:
            return enc(msp.AccTrim(0, 0))
        if cmd == msp.MSP_NAME:
            return enc(msp.CraftName(self.craft_name))
        if cmd == msp.MSP_ANALOG:
            volts, amps = self.battery()
            return enc(msp.Analog(min(255, round(volts * 10)), 0, 0,
                                  _i16(amps * 100), round(volts * 100)))
        if cmd == msp.MSP_RTC:
            now = self.rtc_s()
            return enc(msp.rtc_reply(None if now is None else math.floor(now * 1000)))
        if cmd == msp.MSP_MOTOR:
            vals = self.motors() + [0] * (msp.MOTOR_SLOTS - self.motor_count)
            return enc(msp.Motor(tuple(vals)))
        if cmd in (msp.MSP_RAW_IMU, msp.MSP_ATTITUDE):
            acc, gyro, att = self.imu(time.monotonic() - self._t0)
            if cmd == msp.MSP_ATTITUDE:
                return enc(msp.Attitude(*att))
            counts = tuple(_i16(a / msp.STANDARD_GRAVITY * self.acc_1g) for a in acc)
            rates = tuple(_i16(math.degrees(g) * self.gyro_lsb_per_dps) for g in gyro)
            return enc(msp.RawImu(counts, rates, (0, 0, 0)))  # type: ignore[arg-type]
        return enc(msp.ErrorReply(cmd))

    def rtc_s(self) -> float | None:
        """The FC's clock (seconds since 1970, UTC); None until MSP_SET_RTC set it."""
        offset = self._rtc_offset_s
        return None if offset is None else offset + self.rtc_clock()

    def _reply_with_payload(self, cmd: int, payload: bytes) -> bytes:
        """SET_RTC and MULTIPLE_MSP (see module doc); anything else is refused."""
        if cmd == msp.MSP_SET_RTC and len(payload) == 6:
            seconds, millis = struct.unpack("<iH", payload)
            self._rtc_offset_s = seconds + millis / 1000 - self.rtc_clock()
            return msp.encode_message(msp.Ack(cmd))
        if cmd == msp.MSP_MULTIPLE_MSP and self.multiple and payload:
            parts = bytearray()
            for each in payload:  # a refused command's part is empty
                frame = self._reply(msp.Request(each))
                body = frame[5:-1] if frame[2:3] == msp.REPLY.encode() else b""
                parts += bytes([len(body)]) + body
            return msp.encode_v1(msp.REPLY, cmd, bytes(parts))
        return msp.encode_message(msp.ErrorReply(cmd))
