"""MicroStrain 3DM-GX3-25 single-byte ("legacy") protocol: requests and reply packets.

The reference IMU of the bench. A request is a command byte (plus "confirm intent"
bytes and arguments for some); every reply starts with the same command byte, has a
fixed length per command, big-endian fields and a 16-bit sum checksum. Facts:
protocols.md §2.1-§2.2 (ROS ``microstrain_3dmgx2_imu`` driver, MicroStrain 2009 sample
code, PeRLS header). Firmware >= 2.0 speaks MIP instead (§2.3), not covered here.

Replies are decoded into SI: acceleration m/s² (wire: g), angular rate rad/s, angles rad,
Δvelocity m/s (wire: g·s), magnetic field in gauss (as sent), time in timer ticks plus
seconds (62 500 ticks/s on the GX3).
"""

from __future__ import annotations

import re
import struct
from collections.abc import Sequence
from dataclasses import dataclass

from drivers.codecs.checksums import sum16
from drivers.codecs.stream import NEED_HEADER, Attempt, FrameDecoder, Status

STANDARD_GRAVITY = 9.80665  # m/s² per g; §2.2 "ROS multiplies by G = 9.80665"
TICKS_PER_SECOND = 62_500  # §2.1 TICKS_PER_SEC_GX3 (16 µs/tick); wraps at 2**32
BAUD = 115_200  # §2.1, 8N1

# §2.2 command bytes
RAW_ACCEL_RATE = 0xC1
ACCEL_RATE = 0xC2
DELTA_ANGLE_VELOCITY = 0xC3
SET_CONTINUOUS = 0xC4
ORIENTATION_MATRIX = 0xC5
ATTITUDE_UPDATE_MATRIX = 0xC6
SCALED_MAG = 0xC7
ACCEL_RATE_MATRIX = 0xC8
WRITE_ACCEL_BIAS = 0xC9
WRITE_GYRO_BIAS = 0xCA
ACCEL_RATE_MAG = 0xCB
ACCEL_RATE_MAG_MATRIX = 0xCC
CAPTURE_GYRO_BIAS = 0xCD
EULER = 0xCE
EULER_RATES = 0xCF
TRANSFER_TO_NV = 0xD0
TEMPERATURES = 0xD1
STAB_ACCEL_RATE_MAG = 0xD2
DELTA_ANGLE_VELOCITY_MAG = 0xD3
MODE = 0xD4
MODE_PRESET = 0xD5
CONTINUOUS_PRESET = 0xD6
TIMER = 0xD7
COMM_SETTINGS = 0xD9
STATIONARY_TEST = 0xDA
SAMPLING_SETTINGS = 0xDB
FIRMWARE_VERSION = 0xE9
DEVICE_ID = 0xEA
STOP_CONTINUOUS = 0xFA
DEVICE_RESET = 0xFE

# §2.2 reply length per command byte (header byte .. checksum). 0xFA and 0xFE: no reply.
REPLY_LENGTH: dict[int, int] = {
    0xC1: 31, 0xC2: 31, 0xC3: 31, 0xC4: 8, 0xC5: 43, 0xC6: 43, 0xC7: 19, 0xC8: 67, 0xC9: 19,
    0xCA: 19, 0xCB: 43, 0xCC: 79, 0xCD: 19, 0xCE: 19, 0xCF: 31, 0xD0: 9, 0xD1: 15, 0xD2: 43,
    0xD3: 43, 0xD4: 4, 0xD5: 4, 0xD6: 4, 0xD7: 7, 0xD9: 10, 0xDA: 7, 0xDB: 19, 0xE9: 7,
    0xEA: 20,
}
# §2.2: replies whose layout protocols.md gives as "N floats, then timer u32, checksum u16".
_FLOAT_REPLIES: dict[int, int] = {
    0xC2: 6, 0xC3: 6, 0xC5: 9, 0xC6: 9, 0xC7: 3, 0xC8: 15, 0xCB: 9, 0xCC: 18, 0xCD: 3,
    0xCE: 3, 0xCF: 6, 0xD2: 9,
}

# §2.2 "confirm intent" bytes
_CONFIRM_CONTINUOUS = b"\xC1\x29"
_CONFIRM_STOP = b"\x75\xB4"  # GX3 stop continuous: FA 75 B4
_CONFIRM_RESET = b"\x9E\x3A"
_CONFIRM_GYRO_BIAS = b"\xC1\x29"


# ---------------------------------------------------------------------------- requests


def poll(cmd: int) -> bytes:
    """Single-byte request for a data packet (e.g. ``poll(EULER)``)."""
    if cmd not in REPLY_LENGTH:
        raise ValueError(f"0x{cmd:02X} is not a GX3 command with a reply")
    return bytes([cmd])


def set_continuous(cmd: int) -> bytes:
    """``C4 C1 29 <cmd>``: stream ``cmd`` replies continuously (§2.2)."""
    if cmd not in _FLOAT_REPLIES and cmd != RAW_ACCEL_RATE:
        raise ValueError(f"0x{cmd:02X} is not a GX3 data packet")
    return bytes([SET_CONTINUOUS]) + _CONFIRM_CONTINUOUS + bytes([cmd])


def stop_continuous() -> bytes:
    """``FA 75 B4``: leave continuous mode; no reply (§2.2, GX3 form)."""
    return bytes([STOP_CONTINUOUS]) + _CONFIRM_STOP


def capture_gyro_bias(sampling_ms: int = 10_000) -> bytes:
    """``CD C1 29 <u16 ms BE>``: the device must be still; 19-byte reply (§2.2)."""
    return bytes([CAPTURE_GYRO_BIAS]) + _CONFIRM_GYRO_BIAS + struct.pack(">H", sampling_ms)


def device_reset() -> bytes:
    """``FE 9E 3A``: reset, no reply (§2.2)."""
    return bytes([DEVICE_RESET]) + _CONFIRM_RESET


def device_id(selector: int) -> bytes:
    """``EA <sel>``: device ID string request, 20-byte reply (§2.2)."""
    return bytes([DEVICE_ID, selector])


# ---------------------------------------------------------------------------- replies


@dataclass(frozen=True)
class Timed:
    """Fields every data packet ends with: the device timer (ticks, 62 500 per second)."""

    timer_ticks: int

    @property
    def timer_s(self) -> float:
        return self.timer_ticks / TICKS_PER_SECOND


@dataclass(frozen=True)
class AccelRate(Timed):
    """0xC2 (§2.2): acceleration m/s², angular rate rad/s."""

    acc_m_s2: tuple[float, float, float]
    rate_rad_s: tuple[float, float, float]


@dataclass(frozen=True)
class DeltaAngleVelocity(Timed):
    """0xC3 (§2.2): Δangle rad, Δvelocity m/s (wire: g·s)."""

    dangle_rad: tuple[float, float, float]
    dvel_m_s: tuple[float, float, float]


@dataclass(frozen=True)
class ContinuousAck(Timed):
    """0xC4 ack (§2.2): echo of the command now streamed."""

    cmd: int


@dataclass(frozen=True)
class Matrix(Timed):
    """0xC5 orientation matrix / 0xC6 attitude update matrix, row-major M11..M33 (§2.2)."""

    cmd: int
    matrix: tuple[float, ...]


@dataclass(frozen=True)
class ScaledMag(Timed):
    """0xC7 (§2.2): magnetic field in gauss."""

    mag_gauss: tuple[float, float, float]


@dataclass(frozen=True)
class AccelRateMatrix(Timed):
    """0xC8 (§2.2): acceleration, angular rate and orientation matrix (row-major)."""

    acc_m_s2: tuple[float, float, float]
    rate_rad_s: tuple[float, float, float]
    matrix: tuple[float, ...]


@dataclass(frozen=True)
class AccelRateMag(Timed):
    """0xCB, and 0xD2 gyro-stabilised (``cmd`` tells which) (§2.2)."""

    cmd: int
    acc_m_s2: tuple[float, float, float]
    rate_rad_s: tuple[float, float, float]
    mag_gauss: tuple[float, float, float]


@dataclass(frozen=True)
class AccelRateMagMatrix(Timed):
    """0xCC (§2.2): acceleration, angular rate, magnetic field, orientation matrix."""

    acc_m_s2: tuple[float, float, float]
    rate_rad_s: tuple[float, float, float]
    mag_gauss: tuple[float, float, float]
    matrix: tuple[float, ...]


@dataclass(frozen=True)
class GyroBias(Timed):
    """0xCD reply (§2.2): the captured gyro bias, rad/s."""

    bias_rad_s: tuple[float, float, float]


@dataclass(frozen=True)
class Euler(Timed):
    """0xCE (§2.2): roll, pitch, yaw in radians."""

    roll_rad: float
    pitch_rad: float
    yaw_rad: float


@dataclass(frozen=True)
class EulerRates(Timed):
    """0xCF (§2.2): roll, pitch, yaw (rad) and angular rate (rad/s)."""

    roll_rad: float
    pitch_rad: float
    yaw_rad: float
    rate_rad_s: tuple[float, float, float]


@dataclass(frozen=True)
class Reply:
    """A reply whose field layout protocols.md does not give: raw body between header
    and checksum (e.g. 0xC1 raw sensor values, 0xD1 temperatures, 0xE9 firmware)."""

    cmd: int
    body_hex: str


Gx3Message = (AccelRate | DeltaAngleVelocity | ContinuousAck | Matrix | ScaledMag | AccelRateMatrix
              | AccelRateMag | AccelRateMagMatrix | GyroBias | Euler | EulerRates | Reply)


def _vec(v: Sequence[float], scale: float = 1.0) -> tuple[float, float, float]:
    return (v[0] * scale, v[1] * scale, v[2] * scale)


def parse_reply(cmd: int, body: bytes) -> Gx3Message:
    """Message of a checked reply; ``body`` is everything between header and checksum."""
    g = STANDARD_GRAVITY
    if cmd == SET_CONTINUOUS:
        echo, ticks = struct.unpack(">BI", body)
        return ContinuousAck(ticks, echo)
    if cmd not in _FLOAT_REPLIES:
        return Reply(cmd, body.hex())
    n = _FLOAT_REPLIES[cmd]
    *f, ticks = struct.unpack(f">{n}fI", body)
    if cmd == ACCEL_RATE:
        return AccelRate(ticks, _vec(f[0:3], g), _vec(f[3:6]))
    if cmd == DELTA_ANGLE_VELOCITY:
        return DeltaAngleVelocity(ticks, _vec(f[0:3]), _vec(f[3:6], g))
    if cmd in (ORIENTATION_MATRIX, ATTITUDE_UPDATE_MATRIX):
        return Matrix(ticks, cmd, tuple(f))
    if cmd == SCALED_MAG:
        return ScaledMag(ticks, _vec(f))
    if cmd == ACCEL_RATE_MATRIX:
        return AccelRateMatrix(ticks, _vec(f[0:3], g), _vec(f[3:6]), tuple(f[6:15]))
    if cmd in (ACCEL_RATE_MAG, STAB_ACCEL_RATE_MAG):
        return AccelRateMag(ticks, cmd, _vec(f[0:3], g), _vec(f[3:6]), _vec(f[6:9]))
    if cmd == ACCEL_RATE_MAG_MATRIX:
        return AccelRateMagMatrix(ticks, _vec(f[0:3], g), _vec(f[3:6]), _vec(f[6:9]),
                                  tuple(f[9:18]))
    if cmd == CAPTURE_GYRO_BIAS:
        return GyroBias(ticks, _vec(f))
    if cmd == EULER:
        return Euler(ticks, f[0], f[1], f[2])
    return EulerRates(ticks, f[0], f[1], f[2], _vec(f[3:6]))


def _floats(msg: Gx3Message) -> tuple[int, tuple[float, ...]]:
    g = STANDARD_GRAVITY
    if isinstance(msg, AccelRate):
        return ACCEL_RATE, (*_vec(msg.acc_m_s2, 1 / g), *msg.rate_rad_s)
    if isinstance(msg, DeltaAngleVelocity):
        return DELTA_ANGLE_VELOCITY, (*msg.dangle_rad, *_vec(msg.dvel_m_s, 1 / g))
    if isinstance(msg, Matrix):
        return msg.cmd, msg.matrix
    if isinstance(msg, ScaledMag):
        return SCALED_MAG, msg.mag_gauss
    if isinstance(msg, AccelRateMatrix):
        return ACCEL_RATE_MATRIX, (*_vec(msg.acc_m_s2, 1 / g), *msg.rate_rad_s, *msg.matrix)
    if isinstance(msg, AccelRateMag):
        return msg.cmd, (*_vec(msg.acc_m_s2, 1 / g), *msg.rate_rad_s, *msg.mag_gauss)
    if isinstance(msg, AccelRateMagMatrix):
        return ACCEL_RATE_MAG_MATRIX, (*_vec(msg.acc_m_s2, 1 / g), *msg.rate_rad_s,
                                       *msg.mag_gauss, *msg.matrix)
    if isinstance(msg, GyroBias):
        return CAPTURE_GYRO_BIAS, msg.bias_rad_s
    if isinstance(msg, Euler):
        return EULER, (msg.roll_rad, msg.pitch_rad, msg.yaw_rad)
    if isinstance(msg, EulerRates):
        return EULER_RATES, (msg.roll_rad, msg.pitch_rad, msg.yaw_rad, *msg.rate_rad_s)
    raise TypeError(f"not a GX3 float packet: {msg!r}")


def encode_reply(msg: Gx3Message) -> bytes:
    """Device-side bytes of a reply (for simulators and transcripts)."""
    if isinstance(msg, Reply):
        body = bytes.fromhex(msg.body_hex)
        cmd = msg.cmd
    elif isinstance(msg, ContinuousAck):
        cmd, body = SET_CONTINUOUS, struct.pack(">BI", msg.cmd, msg.timer_ticks & 0xFFFFFFFF)
    else:
        cmd, floats = _floats(msg)
        if len(floats) != _FLOAT_REPLIES[cmd]:
            raise ValueError(f"0x{cmd:02X} takes {_FLOAT_REPLIES[cmd]} floats, got {len(floats)}")
        body = struct.pack(f">{len(floats)}fI", *floats, msg.timer_ticks & 0xFFFFFFFF)
    if len(body) + 3 != REPLY_LENGTH.get(cmd, -1):
        raise ValueError(f"0x{cmd:02X} reply must be {REPLY_LENGTH.get(cmd)} bytes")
    head = bytes([cmd]) + body
    return head + struct.pack(">H", sum16(head))


class Gx3Decoder(FrameDecoder):
    """Resynchronising decoder of the device's reply stream (polled or continuous)."""

    sync = re.compile(b"[" + b"".join(re.escape(bytes([c])) for c in sorted(REPLY_LENGTH)) + b"]")

    def try_frame(self, buf: bytes | bytearray, i: int) -> Attempt:
        cmd = buf[i]
        total = REPLY_LENGTH[cmd]
        if len(buf) - i < total:
            # The header is the command byte alone: a partial reply is judged at flush
            # only if at least 2 bytes of it arrived (so a stray byte is not a frame).
            return NEED_HEADER if len(buf) - i < 2 else Attempt(Status.NEED_BODY)
        frame = memoryview(buf)[i : i + total]
        if sum16(frame[:-2]) != (frame[-2] << 8 | frame[-1]):
            return Attempt(Status.BAD_CHECKSUM, total)
        return Attempt(Status.OK, total, parse_reply(cmd, bytes(frame[1:-2])))


class TimerUnwrapper:
    """Turns the 32-bit device timer into continuous seconds across wraps (§2.1)."""

    def __init__(self) -> None:
        self._last: int | None = None
        self._wraps = 0

    def seconds(self, ticks: int) -> float:
        if self._last is not None and ticks < self._last:
            self._wraps += 1
        self._last = ticks
        return (ticks + self._wraps * 2**32) / TICKS_PER_SECOND
