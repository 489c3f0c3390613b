"""MultiWii Serial Protocol (MSP v1, v2 and v2-over-v1): frames and the bench's messages.

A flight controller serves the bench as IMU under test and as ESC driver. Frames are
``MspFrame`` (version, direction, command id, payload); ``parse(frame)`` turns one into a
typed message and ``encode_message(msg)`` does the reverse. Facts: protocols.md §1 (from
Betaflight ``msp_serial.c``/``msp.c``/``msp_protocol.h``, INAV and MultiWii sources).

Safety: Betaflight applies MSP_SET_MOTOR values only while the FC is *disarmed* (the
Configurator "motor test" path, §1.7) — and then really spins the motors. A driver must
check the arming state before sending ``SetMotor`` and send idle (1000) when done.
"""

from __future__ import annotations

import datetime
import math
import re
import struct
from dataclasses import dataclass
from typing import ClassVar

from drivers.codecs.checksums import crc8_dvb_s2, xor8
from drivers.codecs.stream import NEED_BODY, NEED_HEADER, NOT_A_FRAME, Attempt, FrameDecoder, Status

# §1.1 / §1.2: direction characters
REQUEST = "<"  # to the FC
REPLY = ">"  # from the FC
ERROR = "!"  # error reply (unknown or failed command)
_DIRECTIONS = frozenset(b"<>!")

# §1.3 command ids (msp_protocol.h)
MSP_API_VERSION = 1
MSP_FC_VARIANT = 2
MSP_FC_VERSION = 3
MSP_BOARD_INFO = 4
MSP_BUILD_INFO = 5
MSP_NAME = 10
MSP_STATUS = 101
MSP_RAW_IMU = 102
MSP_MOTOR = 104
MSP_ATTITUDE = 108
MSP_ANALOG = 110
MSP_STATUS_EX = 150
MSP_UID = 160
MSP_ATTITUDE_QUATERNION = 167
MSP_SET_MOTOR = 214
MSP_MULTIPLE_MSP = 230  # Betaflight: several "out" replies for one request (msp.c)
MSP_ACC_TRIM = 240
MSP_SET_RTC = 246  # Betaflight: set the FC's clock (i32 seconds, u16 ms; msp.c)
MSP_RTC = 247  # Betaflight: the FC's clock as a date and time to the millisecond
MSP_V2_FRAME_ID = 255  # §1.1 "MSPv2-over-v1": cmd 255 carries a v2 frame (msp.h)

ARMED_FLAG = 1  # bit 0 of the flight-mode flags: box BOXARM = 0, set while armed (BF msp_box.h)
MOTOR_SLOTS = 8  # §1.5: MSP_MOTOR carries 8 x uint16; MultiWii SET_MOTOR reads exactly 16 bytes
MOTOR_MIN_US = 1000  # §1.5/§1.7: external "PWM-like" scale 1000..2000
MOTOR_MAX_US = 2000
STANDARD_GRAVITY = 9.80665  # m/s² per g (protocols.md §2.2, ROS driver constant G)
INAV_ACC_1G = 512  # §1.4: INAV sends accADCf*512, i.e. 1 g = 512
DEFAULT_MAX_PAYLOAD = 4096  # decoder guard: longer declared sizes are treated as garbage


@dataclass(frozen=True)
class MspFrame:
    """One MSP frame. ``version`` 2 also covers v2 frames tunnelled in v1 (cmd 255)."""

    version: int
    direction: str
    cmd: int
    payload: bytes = b""
    flags: int = 0


# ---------------------------------------------------------------------------- framing


def encode_v1(direction: str, cmd: int, payload: bytes = b"") -> bytes:
    """MSP v1 frame (§1.1); replies of 255 bytes or more use the Betaflight JUMBO form."""
    if not 0 <= cmd <= 255:
        raise ValueError(f"MSP v1 command id must be 0..255, got {cmd}")
    if len(payload) >= 255:
        if direction == REQUEST:
            raise ValueError("MSP v1 requests are limited to 254 bytes (no jumbo requests)")
        if len(payload) > 0xFFFF:
            raise ValueError("MSP v1 jumbo payload is limited to 65535 bytes")
        body = bytes([0xFF, cmd]) + struct.pack("<H", len(payload)) + payload
    else:
        body = bytes([len(payload), cmd]) + payload
    return b"$M" + direction.encode() + body + bytes([xor8(body)])


def encode_v2(direction: str, cmd: int, payload: bytes = b"", flags: int = 0) -> bytes:
    """MSP v2 native frame (§1.2): ``$X`` dir, flags u8, cmd u16 LE, size u16 LE, CRC8."""
    body = _v2_body(cmd, payload, flags)
    return b"$X" + direction.encode() + body + bytes([crc8_dvb_s2(body)])


def encode_v2_over_v1(direction: str, cmd: int, payload: bytes = b"", flags: int = 0) -> bytes:
    """A v2 frame tunnelled in a v1 frame with cmd 255 (§1.1)."""
    body = _v2_body(cmd, payload, flags)
    return encode_v1(direction, MSP_V2_FRAME_ID, body + bytes([crc8_dvb_s2(body)]))


def _v2_body(cmd: int, payload: bytes, flags: int) -> bytes:
    if not 0 <= cmd <= 0xFFFF or not 0 <= flags <= 0xFF or len(payload) > 0xFFFF:
        raise ValueError(f"MSP v2 field out of range: cmd={cmd} flags={flags} size={len(payload)}")
    return struct.pack("<BHH", flags, cmd, len(payload)) + payload


def encode_frame(frame: MspFrame) -> bytes:
    if frame.version == 1:
        return encode_v1(frame.direction, frame.cmd, frame.payload)
    return encode_v2(frame.direction, frame.cmd, frame.payload, frame.flags)


def request(cmd: int, version: int = 1) -> bytes:
    """An empty request for an "out" message (§1.1: requests for out messages have size 0)."""
    return encode_v1(REQUEST, cmd) if version == 1 else encode_v2(REQUEST, cmd)


class MspDecoder(FrameDecoder):
    """Resynchronising decoder of a byte stream holding v1, v2 and v2-over-v1 frames.

    Yields ``MspFrame``s, or typed messages (``parse``) with ``typed=True``; then a frame
    whose payload does not fit its command is counted as malformed and dropped.
    """

    sync = re.compile(rb"\$")

    def __init__(self, max_payload: int = DEFAULT_MAX_PAYLOAD, *, typed: bool = False) -> None:
        super().__init__()
        self.max_payload = max_payload
        self.typed = typed

    def try_frame(self, buf: bytes | bytearray, i: int) -> Attempt:
        att = self._try_raw(buf, i)
        if not self.typed or att.status is not Status.OK or att.message is None:
            return att
        try:
            return Attempt(Status.OK, att.length, parse(att.message))
        except PayloadError:
            return Attempt(Status.MALFORMED, att.length)

    def _try_raw(self, buf: bytes | bytearray, i: int) -> Attempt[MspFrame]:
        n = len(buf) - i
        if n >= 2 and buf[i + 1] not in b"MX":
            return NOT_A_FRAME
        if n >= 3 and buf[i + 2] not in _DIRECTIONS:
            return NOT_A_FRAME
        if n < 3:
            return NEED_HEADER
        direction = chr(buf[i + 2])
        if buf[i + 1] == ord("M"):
            return self._try_v1(buf, i, n, direction)
        return self._try_v2(buf, i, n, direction)

    def _try_v1(self, buf: bytes | bytearray, i: int, n: int, direction: str) -> Attempt[MspFrame]:
        if n < 5:
            return NEED_HEADER
        size, cmd, hdr = buf[i + 3], buf[i + 4], 5
        if size == 0xFF and direction != REQUEST:  # §1.1 JUMBO reply
            if n < 7:
                return NEED_HEADER
            size, hdr = buf[i + 5] | buf[i + 6] << 8, 7
        if size > self.max_payload:
            return NOT_A_FRAME
        total = hdr + size + 1
        if n < total:
            return NEED_BODY
        if xor8(memoryview(buf)[i + 3 : i + total - 1]) != buf[i + total - 1]:
            return Attempt(Status.BAD_CHECKSUM, total)
        payload = bytes(buf[i + hdr : i + total - 1])
        if cmd != MSP_V2_FRAME_ID:
            return Attempt(Status.OK, total, MspFrame(1, direction, cmd, payload))
        # §1.1 v2-over-v1: payload = v2 header + payload + v2 CRC8
        if len(payload) < 6:
            return Attempt(Status.MALFORMED, total)
        flags, cmd2, size2 = struct.unpack_from("<BHH", payload)
        if size2 != len(payload) - 6:
            return Attempt(Status.MALFORMED, total)
        if crc8_dvb_s2(payload[:-1]) != payload[-1]:
            return Attempt(Status.BAD_CHECKSUM, total)
        return Attempt(Status.OK, total, MspFrame(2, direction, cmd2, payload[5:-1], flags))

    def _try_v2(self, buf: bytes | bytearray, i: int, n: int, direction: str) -> Attempt[MspFrame]:
        if n < 8:
            return NEED_HEADER
        flags, cmd, size = struct.unpack_from("<BHH", buf, i + 3)
        if size > self.max_payload:
            return NOT_A_FRAME
        total = 8 + size + 1
        if n < total:
            return NEED_BODY
        if crc8_dvb_s2(memoryview(buf)[i + 3 : i + total - 1]) != buf[i + total - 1]:
            return Attempt(Status.BAD_CHECKSUM, total)
        payload = bytes(buf[i + 8 : i + total - 1])
        return Attempt(Status.OK, total, MspFrame(2, direction, cmd, payload, flags))


# ---------------------------------------------------------------------------- messages


class PayloadError(ValueError):
    """A frame's payload does not fit the layout of its command (counted as malformed)."""


@dataclass(frozen=True)
class Request:
    """An empty request for an "out" message (size 0, §1.1)."""

    cmd: int


@dataclass(frozen=True)
class Ack:
    """The empty reply to an "in" (SET) command, e.g. SET_MOTOR (§1.1)."""

    cmd: int


@dataclass(frozen=True)
class ErrorReply:
    """``$M!``: unknown or failed command (§1.1)."""

    cmd: int


@dataclass(frozen=True)
class Unknown:
    """A valid frame of a command this codec does not interpret."""

    direction: str
    cmd: int
    payload_hex: str


@dataclass(frozen=True)
class ApiVersion:
    """MSP_API_VERSION reply (§1.3): u8 protocol, u8 api major, u8 api minor."""

    CMD: ClassVar[int] = MSP_API_VERSION
    protocol: int
    api_major: int
    api_minor: int

    def to_payload(self) -> bytes:
        return bytes([self.protocol, self.api_major, self.api_minor])

    @classmethod
    def from_payload(cls, p: bytes) -> ApiVersion:
        _need(p, 3, exact=False)
        return cls(p[0], p[1], p[2])


@dataclass(frozen=True)
class FcVariant:
    """MSP_FC_VARIANT reply (§1.3): 4 ASCII characters such as "BTFL" or "INAV"."""

    CMD: ClassVar[int] = MSP_FC_VARIANT
    name: str

    def to_payload(self) -> bytes:
        raw = self.name.encode("ascii")
        if len(raw) != 4:
            raise ValueError(f"FC variant must be 4 ASCII characters, got {self.name!r}")
        return raw

    @classmethod
    def from_payload(cls, p: bytes) -> FcVariant:
        _need(p, 4, exact=False)
        return cls(p[:4].decode("ascii", errors="replace"))


@dataclass(frozen=True)
class FcStatus:
    """MSP_STATUS reply, the 11-byte prefix common to Betaflight, INAV and MultiWii (§1.8).

    Which bit of ``flight_mode_flags`` means "armed" is firmware-specific and not in
    protocols.md; the remaining Betaflight fields are kept raw in ``rest_hex``.
    """

    CMD: ClassVar[int] = MSP_STATUS
    cycle_time_us: int
    i2c_errors: int
    sensors: int
    flight_mode_flags: int
    profile: int
    rest_hex: str = ""

    def to_payload(self) -> bytes:
        return struct.pack("<HHHIB", self.cycle_time_us, self.i2c_errors, self.sensors,
                           self.flight_mode_flags, self.profile) + bytes.fromhex(self.rest_hex)

    @classmethod
    def from_payload(cls, p: bytes) -> FcStatus:
        _need(p, 11, exact=False)
        return cls(*struct.unpack_from("<HHHIB", p), rest_hex=p[11:].hex())


@dataclass(frozen=True)
class FcVersion:
    """MSP_FC_VERSION reply: u8 major, minor, patch (BF ``msp.c``; yamspy
    ``process_MSP_FC_VERSION``)."""

    CMD: ClassVar[int] = MSP_FC_VERSION
    major: int
    minor: int
    patch: int

    def to_payload(self) -> bytes:
        return bytes([self.major, self.minor, self.patch])

    @classmethod
    def from_payload(cls, p: bytes) -> FcVersion:
        _need(p, 3, exact=False)
        return cls(p[0], p[1], p[2])

    def __str__(self) -> str:
        return f"{self.major}.{self.minor}.{self.patch}"


def _pascal(p: bytes, at: int) -> tuple[str, int]:
    """A u8-length-prefixed string at ``at`` -> (text, offset after it)."""
    _need(p, at + 1, exact=False)
    n = p[at]
    _need(p, at + 1 + n, exact=False)
    return p[at + 1:at + 1 + n].decode("ascii", errors="replace"), at + 1 + n


@dataclass(frozen=True)
class BoardInfo:
    """MSP_BOARD_INFO reply, Betaflight layout (BF ``msp.c``; yamspy
    ``process_MSP_BOARD_INFO``): 4-char board id, u16 hardware revision, u8 board type
    (0 = FC), u8 target capabilities, u8-prefixed target name, board name and
    manufacturer id, 32-byte signature, u8 MCU type id; anything after is kept raw."""

    CMD: ClassVar[int] = MSP_BOARD_INFO
    board_id: str
    hw_revision: int = 0
    board_type: int = 0
    capabilities: int = 0
    target_name: str = ""
    board_name: str = ""
    manufacturer_id: str = ""
    signature_hex: str = "00" * 32
    mcu_type: int = 255
    rest_hex: str = ""

    def to_payload(self) -> bytes:
        def pascal(text: str) -> bytes:
            raw = text.encode("ascii")
            return bytes([len(raw)]) + raw

        board = self.board_id.encode("ascii")
        if len(board) != 4:
            raise ValueError(f"board id must be 4 ASCII characters, got {self.board_id!r}")
        return (board + struct.pack("<HBB", self.hw_revision, self.board_type,
                                    self.capabilities)
                + pascal(self.target_name) + pascal(self.board_name)
                + pascal(self.manufacturer_id) + bytes.fromhex(self.signature_hex)
                + bytes([self.mcu_type]) + bytes.fromhex(self.rest_hex))

    @classmethod
    def from_payload(cls, p: bytes) -> BoardInfo:
        _need(p, 8, exact=False)
        hw, kind, caps = struct.unpack_from("<HBB", p, 4)
        target, at = _pascal(p, 8)
        if at == len(p):  # older firmware: no board name and the rest
            return cls(p[:4].decode("ascii", errors="replace"), hw, kind, caps, target)
        board, at = _pascal(p, at)
        maker, at = _pascal(p, at)
        _need(p, at + 33, exact=False)
        return cls(p[:4].decode("ascii", errors="replace"), hw, kind, caps, target, board, maker,
                   p[at:at + 32].hex(), p[at + 32], p[at + 33:].hex())


@dataclass(frozen=True)
class StatusEx:
    """MSP_STATUS_EX reply, Betaflight layout (§1.8; yamspy ``process_MSP_STATUS_EX``):
    the STATUS prefix, u16 system load, u8 PID profile count, u8 rate profile, u8 count +
    extra flight-mode flag bytes, u8 arming-disable flag count, u32 arming-disable flags,
    then the rest (config state, CPU temperature, ...) kept raw.

    ``armed``: bit 0 of the flight-mode flags (``ARMED_FLAG``)."""

    CMD: ClassVar[int] = MSP_STATUS_EX
    cycle_time_us: int
    i2c_errors: int
    sensors: int
    flight_mode_flags: int
    profile: int
    system_load: int = 0
    profile_count: int = 1
    rate_profile: int = 0
    extra_flags_hex: str = ""
    arming_disable_count: int = 0
    arming_disable_flags: int = 0
    rest_hex: str = ""

    @property
    def armed(self) -> bool:
        return bool(self.flight_mode_flags & ARMED_FLAG)

    def to_payload(self) -> bytes:
        extra = bytes.fromhex(self.extra_flags_hex)
        return (struct.pack("<HHHIBHBBB", self.cycle_time_us, self.i2c_errors, self.sensors,
                            self.flight_mode_flags, self.profile, self.system_load,
                            self.profile_count, self.rate_profile, len(extra))
                + extra + struct.pack("<BI", self.arming_disable_count,
                                      self.arming_disable_flags)
                + bytes.fromhex(self.rest_hex))

    @classmethod
    def from_payload(cls, p: bytes) -> StatusEx:
        _need(p, 16, exact=False)
        head = struct.unpack_from("<HHHIBHBBB", p)
        n = head[-1]
        _need(p, 16 + n + 5, exact=False)
        disable_count, disable = struct.unpack_from("<BI", p, 16 + n)
        return cls(*head[:-1], p[16:16 + n].hex(), disable_count, disable,
                   p[16 + n + 5:].hex())


@dataclass(frozen=True)
class Analog:
    """MSP_ANALOG reply, Betaflight layout (§1.8 "other replies"; yamspy
    ``process_MSP_ANALOG``): u8 legacy vbat (0.1 V), u16 mAh drawn, u16 rssi (0..1023),
    i16 current (0.01 A), u16 voltage (0.01 V). INAV sends only the first 7 bytes."""

    CMD: ClassVar[int] = MSP_ANALOG
    vbat_legacy_dv: int
    mah_drawn: int
    rssi: int
    current_ca: int
    voltage_cv: int | None = None

    @property
    def voltage_v(self) -> float:
        return (self.voltage_cv / 100.0 if self.voltage_cv is not None
                else self.vbat_legacy_dv / 10.0)

    @property
    def current_a(self) -> float:
        return self.current_ca / 100.0

    def to_payload(self) -> bytes:
        out = struct.pack("<BHHh", self.vbat_legacy_dv, self.mah_drawn, self.rssi,
                          self.current_ca)
        return out if self.voltage_cv is None else out + struct.pack("<H", self.voltage_cv)

    @classmethod
    def from_payload(cls, p: bytes) -> Analog:
        _need(p, 7, exact=False)
        head = struct.unpack_from("<BHHh", p)
        return cls(*head, struct.unpack_from("<H", p, 7)[0] if len(p) >= 9 else None)


@dataclass(frozen=True)
class RawImu:
    """MSP_RAW_IMU reply (§1.4): 9 x int16 LE. Units depend on the firmware; see ``imu_si``."""

    CMD: ClassVar[int] = MSP_RAW_IMU
    acc: tuple[int, int, int]
    gyro: tuple[int, int, int]
    mag: tuple[int, int, int]

    def to_payload(self) -> bytes:
        return struct.pack("<9h", *self.acc, *self.gyro, *self.mag)

    @classmethod
    def from_payload(cls, p: bytes) -> RawImu:
        _need(p, 18)
        v = struct.unpack("<9h", p)
        return cls(v[0:3], v[3:6], v[6:9])


#: Betaflight's RAW_IMU gyro is ``gyroADCf / gyro.scale`` (msp.c): the sensor's own counts,
#: 16.4 per deg/s for the +-2000 deg/s range its gyros run at (MPU6000, ICM-426xx, BMI270)
#: and for the SITL's virtual gyro, measured on Betaflight 4.6.0 (docs/protocols.md).
#: INAV sends whole deg/s (``gyroRateDps``).
BTFL_GYRO_LSB_PER_DPS = 16.4


def imu_si(msg: RawImu, variant: str, acc_1g: float | None = None, *,
           gyro_lsb_per_dps: float | None = None
           ) -> tuple[tuple[float, float, float], tuple[float, float, float]]:
    """Acceleration (m/s²) and angular rate (rad/s) of a RAW_IMU reply (§1.4).

    Betaflight ("BTFL"): acc in driver counts with 1 g = ``acc_1g`` (e.g. 2048 for an
    MPU6050, 256 for the SITL), which the caller must give; the gyro in sensor counts,
    ``BTFL_GYRO_LSB_PER_DPS`` per deg/s unless ``gyro_lsb_per_dps`` says otherwise (a
    gyro run at another range). INAV: 1 g = 512, the gyro in whole deg/s (§1.4's "deg/s"
    holds for INAV only). MultiWii sends raw sensor counts whose scale protocols.md does
    not give: refused.
    """
    if variant == "INAV":
        one_g = float(INAV_ACC_1G if acc_1g is None else acc_1g)
        lsb = 1.0 if gyro_lsb_per_dps is None else gyro_lsb_per_dps
    elif variant == "BTFL":
        if acc_1g is None:
            raise ValueError("Betaflight RAW_IMU acc is in driver counts: give acc_1g")
        one_g = float(acc_1g)
        lsb = BTFL_GYRO_LSB_PER_DPS if gyro_lsb_per_dps is None else gyro_lsb_per_dps
    else:
        raise ValueError(f"RAW_IMU scaling unknown for FC variant {variant!r} (§1.4)")
    acc = tuple(a / one_g * STANDARD_GRAVITY for a in msg.acc)
    gyro = tuple(math.radians(g / lsb) for g in msg.gyro)
    return acc, gyro  # type: ignore[return-value]


@dataclass(frozen=True)
class Attitude:
    """MSP_ATTITUDE reply (§1.5), in radians.

    On the wire: roll and pitch int16 in 0.1°, yaw (heading) int16 in whole degrees.
    """

    CMD: ClassVar[int] = MSP_ATTITUDE
    roll_rad: float
    pitch_rad: float
    yaw_rad: float

    def to_payload(self) -> bytes:
        return struct.pack("<3h", round(math.degrees(self.roll_rad) * 10),
                           round(math.degrees(self.pitch_rad) * 10),
                           round(math.degrees(self.yaw_rad)))

    @classmethod
    def from_payload(cls, p: bytes) -> Attitude:
        _need(p, 6)
        r, pi, y = struct.unpack("<3h", p)
        return cls(math.radians(r / 10), math.radians(pi / 10), math.radians(y))


Quat = tuple[float, float, float, float]  # scalar first (w, x, y, z)
#: the frame changes between Betaflight's axes and the bench's, as quaternions: forward-
#: right-down body from forward-left-up (half a turn about x); north-east-down earth from
#: east-north-up (half a turn about the bisector of x and y)
FRD_FROM_FLU: Quat = (0.0, 1.0, 0.0, 0.0)
NED_FROM_ENU: Quat = (0.0, math.sqrt(0.5), math.sqrt(0.5), 0.0)


def quat_mul(a: Quat, b: Quat) -> Quat:
    """Hamilton product ``a ⊗ b`` (rotation ``b`` first, then ``a``)."""
    aw, ax, ay, az = a
    bw, bx, by, bz = b
    return (aw * bw - ax * bx - ay * by - az * bz, aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx, aw * bz + ax * by - ay * bx + az * bw)


def quat_conj(q: Quat) -> Quat:
    return (q[0], -q[1], -q[2], -q[3])


def attitude_quat_enu(att: Attitude) -> Quat:
    """Betaflight's MSP_ATTITUDE (roll right wing down +, pitch **nose down** +, yaw the
    compass heading, clockwise from north) as the quaternion forward-left-up body →
    east-north-up earth, the bench's attitude convention.

    Betaflight's angles are the Z-Y-X Euler angles of its FRD body in NED with the pitch
    negated (imu.c); the frame changes then turn that rotation into FLU → ENU."""
    half = (0.5 * att.yaw_rad, -0.5 * att.pitch_rad, 0.5 * att.roll_rad)
    (cy, cp, cr), (sy, sp, sr) = (tuple(math.cos(h) for h in half),
                                  tuple(math.sin(h) for h in half))
    ned_frd = (cr * cp * cy + sr * sp * sy, sr * cp * cy - cr * sp * sy,
               cr * sp * cy + sr * cp * sy, cr * cp * sy - sr * sp * cy)
    return quat_mul(quat_mul(quat_conj(NED_FROM_ENU), ned_frd), quat_conj(FRD_FROM_FLU))


@dataclass(frozen=True)
class AttitudeQuaternion:
    """MSP_ATTITUDE_QUATERNION reply (Betaflight, §1.8): int16 w, x, y, z scaled by 0x7FFF."""

    CMD: ClassVar[int] = MSP_ATTITUDE_QUATERNION
    w: float
    x: float
    y: float
    z: float

    def to_payload(self) -> bytes:
        return struct.pack("<4h", *(round(c * 0x7FFF) for c in (self.w, self.x, self.y, self.z)))

    @classmethod
    def from_payload(cls, p: bytes) -> AttitudeQuaternion:
        _need(p, 8)
        return cls(*(c / 0x7FFF for c in struct.unpack("<4h", p)))


@dataclass(frozen=True)
class Motor:
    """MSP_MOTOR reply (§1.5): uint16 per motor on the 1000..2000 scale, 0 = unused."""

    CMD: ClassVar[int] = MSP_MOTOR
    values_us: tuple[int, ...]

    def to_payload(self) -> bytes:
        return struct.pack(f"<{len(self.values_us)}H", *self.values_us)

    @classmethod
    def from_payload(cls, p: bytes) -> Motor:
        if len(p) % 2:
            raise PayloadError(f"MSP_MOTOR payload must hold uint16 values, got {len(p)} bytes")
        return cls(struct.unpack(f"<{len(p) // 2}H", p))


@dataclass(frozen=True)
class SetMotor:
    """MSP_SET_MOTOR request (§1.7): uint16 LE per motor, 1000..2000.

    Applied by the FC only while disarmed (motor test), and then the motors spin.
    Fewer than 8 values are padded with 1000 (stop): Betaflight needs at least
    motorCount values, MultiWii reads exactly 16 bytes.
    """

    CMD: ClassVar[int] = MSP_SET_MOTOR
    values_us: tuple[int, ...]

    def to_payload(self) -> bytes:
        vals = tuple(self.values_us)
        if len(vals) > MOTOR_SLOTS:
            raise ValueError(f"MSP_SET_MOTOR takes at most {MOTOR_SLOTS} motors, got {len(vals)}")
        bad = [v for v in vals if not MOTOR_MIN_US <= v <= MOTOR_MAX_US]
        if bad:
            raise ValueError(f"MSP_SET_MOTOR values must be {MOTOR_MIN_US}..{MOTOR_MAX_US}, "
                             f"got {bad}")
        vals += (MOTOR_MIN_US,) * (MOTOR_SLOTS - len(vals))
        return struct.pack(f"<{MOTOR_SLOTS}H", *vals)

    @classmethod
    def from_payload(cls, p: bytes) -> SetMotor:
        if len(p) % 2 or not p:
            raise PayloadError(f"MSP_SET_MOTOR payload must hold uint16 values, got {len(p)} bytes")
        return cls(struct.unpack(f"<{len(p) // 2}H", p))


@dataclass(frozen=True)
class BuildInfo:
    """MSP_BUILD_INFO reply: build date (11 chars, "MMM DD YYYY"), build time (8 chars,
    "HH:MM:SS"), short git revision (BF ``build/version.h`` lengths; yamspy
    ``process_MSP_BUILD_INFO`` reads date and time); anything after is kept raw."""

    CMD: ClassVar[int] = MSP_BUILD_INFO
    date: str
    time: str
    revision: str = ""

    def to_payload(self) -> bytes:
        if len(self.date) != 11 or len(self.time) != 8:
            raise PayloadError("MSP_BUILD_INFO: date must be 11 and time 8 characters")
        return (self.date + self.time + self.revision).encode("ascii")

    @classmethod
    def from_payload(cls, p: bytes) -> BuildInfo:
        _need(p, 19, exact=False)
        text = p.decode("ascii", errors="replace")
        return cls(text[:11], text[11:19], text[19:])


@dataclass(frozen=True)
class Uid:
    """MSP_UID reply: the MCU's 96-bit unique id as three u32 (yamspy ``process_MSP_UID``)."""

    CMD: ClassVar[int] = MSP_UID
    words: tuple[int, int, int]

    def to_payload(self) -> bytes:
        return struct.pack("<3I", *self.words)

    @classmethod
    def from_payload(cls, p: bytes) -> Uid:
        _need(p, 12)
        return cls(struct.unpack("<3I", p))


@dataclass(frozen=True)
class AccTrim:
    """MSP_ACC_TRIM reply: i16 pitch and roll trims (yamspy ``process_MSP_ACC_TRIM``)."""

    CMD: ClassVar[int] = MSP_ACC_TRIM
    pitch: int
    roll: int

    def to_payload(self) -> bytes:
        return struct.pack("<hh", self.pitch, self.roll)

    @classmethod
    def from_payload(cls, p: bytes) -> AccTrim:
        _need(p, 4)
        return cls(*struct.unpack("<hh", p))


@dataclass(frozen=True)
class CraftName:
    """MSP_NAME reply: the craft name, the whole payload, no length byte (yamspy
    ``process_MSP_NAME`` reads to the end); empty when none is set."""

    CMD: ClassVar[int] = MSP_NAME
    name: str

    def to_payload(self) -> bytes:
        return self.name.encode("ascii")

    @classmethod
    def from_payload(cls, p: bytes) -> CraftName:
        return cls(p.decode("ascii", errors="replace"))


MspMessage = (Request | Ack | ErrorReply | Unknown | ApiVersion | FcVariant | FcStatus | RawImu
              | Attitude | AttitudeQuaternion | Motor | SetMotor | FcVersion | BoardInfo
              | StatusEx | Analog | BuildInfo | Uid | AccTrim | CraftName)

_REPLIES: dict[int, type] = {c.CMD: c for c in (ApiVersion, FcVariant, FcStatus, RawImu, Attitude,
                                                AttitudeQuaternion, Motor, FcVersion, BoardInfo,
                                                StatusEx, Analog, BuildInfo, Uid, AccTrim,
                                                CraftName)}
_IN_COMMANDS: dict[int, type] = {MSP_SET_MOTOR: SetMotor}


def _need(p: bytes, n: int, *, exact: bool = True) -> None:
    if (len(p) != n) if exact else (len(p) < n):
        want = f"{n}" if exact else f"at least {n}"
        raise PayloadError(f"payload of {len(p)} bytes, expected {want}")


def parse(frame: MspFrame) -> MspMessage:
    """Typed message of a frame; raises ``PayloadError`` when the payload does not fit."""
    if frame.direction == ERROR:
        return ErrorReply(frame.cmd)
    if frame.direction == REQUEST:
        if frame.cmd in _IN_COMMANDS:
            return _IN_COMMANDS[frame.cmd].from_payload(frame.payload)
        if not frame.payload:
            return Request(frame.cmd)
        return Unknown(frame.direction, frame.cmd, frame.payload.hex())
    if frame.cmd in _IN_COMMANDS and not frame.payload:
        return Ack(frame.cmd)
    if frame.cmd in _REPLIES:
        return _REPLIES[frame.cmd].from_payload(frame.payload)
    return Unknown(frame.direction, frame.cmd, frame.payload.hex())


def set_rtc_request(seconds: int, millis: int = 0) -> Unknown:
    """Betaflight's MSP_SET_RTC: the FC's clock set to ``seconds`` since 1970 (UTC) and
    ``millis``; it then counts on from its own millisecond timer (common/time.c rtcGet)."""
    return Unknown(REQUEST, MSP_SET_RTC, struct.pack("<iH", seconds, millis).hex())


def rtc_ms(reply: MspMessage) -> int | None:
    """Milliseconds since 1970 (UTC) of an MSP_RTC reply; None when the FC's clock was
    never set (an empty reply) or the reply is not one."""
    if not isinstance(reply, Unknown) or reply.cmd != MSP_RTC:
        return None
    payload = bytes.fromhex(reply.payload_hex)
    if len(payload) != 9:
        return None
    year, month, day, hours, minutes, seconds, millis = struct.unpack("<HBBBBBH", payload)
    try:
        at = datetime.datetime(year, month, day, hours, minutes, seconds,
                               tzinfo=datetime.UTC)
    except ValueError:
        return None
    return int(at.timestamp()) * 1000 + millis


def rtc_reply(ms: int | None) -> Unknown:
    """The FC's MSP_RTC reply (``rtc_ms`` reads it): the date and time of ``ms`` since 1970
    (UTC), to the millisecond; empty when its clock was never set."""
    if ms is None:
        return Unknown(REPLY, MSP_RTC, "")
    at = datetime.datetime.fromtimestamp(ms // 1000, datetime.UTC)
    return Unknown(REPLY, MSP_RTC, struct.pack("<HBBBBBH", at.year, at.month, at.day, at.hour,
                                               at.minute, at.second, ms % 1000).hex())


def multiple_request(cmds: tuple[int, ...]) -> Unknown:
    """Betaflight's MSP_MULTIPLE_MSP: one request whose payload lists "out" commands (one
    byte each), answered in one reply, so in one run of the firmware's serial task, which
    serves one command per run (4.6.0 msp_serial.c:486-510, msp.c:2406-2437)."""
    if not cmds or not all(0 <= c <= 255 for c in cmds):
        raise ValueError(f"MSP_MULTIPLE_MSP takes 1-byte command ids, got {cmds}")
    return Unknown(REQUEST, MSP_MULTIPLE_MSP, bytes(cmds).hex())


def _multiple_walk(reply: MspMessage) -> tuple[list[bytes], int]:
    """The whole size-prefixed parts of a MSP_MULTIPLE_MSP reply (a u8 size, then the
    payload, per command it answers) and how many bytes follow the last of them."""
    if not isinstance(reply, Unknown) or reply.cmd != MSP_MULTIPLE_MSP:
        raise PayloadError(f"not a MSP_MULTIPLE_MSP reply: {reply!r}")
    p, at, parts = bytes.fromhex(reply.payload_hex), 0, []
    while at < len(p) and at + 1 + p[at] <= len(p):
        parts.append(p[at + 1:at + 1 + p[at]])
        at += 1 + p[at]
    return parts, len(p) - at


def multiple_parts(reply: MspMessage) -> list[bytes]:
    """The payloads of a MSP_MULTIPLE_MSP reply, one per command it answers;
    ``PayloadError`` if it is not one or its last part is cut."""
    parts, rest = _multiple_walk(reply)
    if rest:
        raise PayloadError(f"MSP_MULTIPLE_MSP reply: its last part is cut ({rest} bytes)")
    return parts


def parse_multiple(cmds: tuple[int, ...], parts: list[bytes]) -> list[MspMessage]:
    """The typed replies to ``cmds`` out of the first of ``parts`` (``multiple_parts``)."""
    return [parse(MspFrame(1, REPLY, cmd, part)) for cmd, part in zip(cmds, parts, strict=False)]


def split_multiple(cmds: tuple[int, ...], reply: MspMessage) -> list[MspMessage]:
    """The typed replies in a MSP_MULTIPLE_MSP reply, exactly one part per command; the
    firmware leaves out the commands that did not fit its buffer, which is a
    ``PayloadError`` here, as is any other mismatch."""
    parts, rest = _multiple_walk(reply)
    if len(parts) < len(cmds):
        size = rest + sum(1 + len(part) for part in parts)
        raise PayloadError(f"MSP_MULTIPLE_MSP reply of {size} bytes ends before "
                           f"{cmds[len(parts)]}")
    left = rest + sum(1 + len(part) for part in parts[len(cmds):])
    if left:
        raise PayloadError(f"MSP_MULTIPLE_MSP reply has {left} bytes left over")
    return parse_multiple(cmds, parts)


def encode_message(msg: MspMessage, version: int = 1) -> bytes:
    """Bytes of a typed message: requests from the host, replies from the FC."""
    enc = encode_v1 if version == 1 else encode_v2
    if isinstance(msg, Request):
        return enc(REQUEST, msg.cmd)
    if isinstance(msg, Ack):
        return enc(REPLY, msg.cmd)
    if isinstance(msg, ErrorReply):
        return enc(ERROR, msg.cmd)
    if isinstance(msg, Unknown):
        return enc(msg.direction, msg.cmd, bytes.fromhex(msg.payload_hex))
    direction = REQUEST if isinstance(msg, SetMotor) else REPLY
    return enc(direction, msg.CMD, msg.to_payload())
