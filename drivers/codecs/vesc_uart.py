"""VESC over USB/UART: packet framing and the bench's commands (protocols.md §3.3-§3.4).

A packet is ``0x02, u8 length`` (payload <= 255) or ``0x03, u16 BE length`` (256..65535),
then the payload (command id + data), a CRC-16/XMODEM of the payload (big-endian) and
``0x03`` (``comm/packet.c``); zero-length payloads are refused and the firmware's
``PACKET_MAX_PL_LEN`` is 512. Set-commands use the CAN scalings (duty x 1e5, current x 1e3
mA, ERPM) and get no reply; ``GET_VALUES`` answers the field table of §3.4 (74 payload
bytes on current firmware, a prefix on older ones: parsed by length). ``ALIVE`` only
refreshes the firmware's command timeout (1 s, ``APPCONF_TIMEOUT_MSEC``, §3.2).
"""

from __future__ import annotations

import re
import struct
from dataclasses import dataclass
from typing import ClassVar

from drivers.codecs.checksums import crc16_xmodem
from drivers.codecs.stream import NEED_BODY, NEED_HEADER, NOT_A_FRAME, Attempt, FrameDecoder, Status

# §3.3 COMM_PACKET_ID
COMM_FW_VERSION = 0
COMM_GET_VALUES = 4
COMM_SET_DUTY = 5
COMM_SET_CURRENT = 6
COMM_SET_CURRENT_BRAKE = 7
COMM_SET_RPM = 8
COMM_ALIVE = 30
MAX_PAYLOAD = 512  # PACKET_MAX_PL_LEN
BAUD = 115_200  # APPCONF_UART_BAUDRATE (a USB CDC port ignores it)


def frame(payload: bytes) -> bytes:
    """One packet around ``payload`` (command id first), §3.3."""
    n = len(payload)
    if not 0 < n <= 0xFFFF:
        raise ValueError(f"VESC packet payload must be 1..65535 bytes, got {n}")
    head = bytes([2, n]) if n <= 0xFF else bytes([3]) + struct.pack(">H", n)
    return head + payload + struct.pack(">H", crc16_xmodem(payload)) + b"\x03"


# ---------------------------------------------------------------------------- messages


class PayloadError(ValueError):
    """A packet's payload does not fit the layout of its command."""


@dataclass(frozen=True)
class Request:
    """A command without data: GET_VALUES, ALIVE, FW_VERSION requests."""

    cmd: int

    def to_payload(self) -> bytes:
        return bytes([self.cmd])


@dataclass(frozen=True)
class SetDuty:
    CMD: ClassVar[int] = COMM_SET_DUTY
    duty: float  # -1..1

    def to_payload(self) -> bytes:
        return bytes([self.CMD]) + struct.pack(">i", round(self.duty * 1e5))


@dataclass(frozen=True)
class SetCurrent:
    CMD: ClassVar[int] = COMM_SET_CURRENT
    current_a: float

    def to_payload(self) -> bytes:
        return bytes([self.CMD]) + struct.pack(">i", round(self.current_a * 1e3))


@dataclass(frozen=True)
class SetCurrentBrake:
    CMD: ClassVar[int] = COMM_SET_CURRENT_BRAKE
    current_a: float

    def to_payload(self) -> bytes:
        return bytes([self.CMD]) + struct.pack(">i", round(self.current_a * 1e3))


@dataclass(frozen=True)
class SetRpm:
    CMD: ClassVar[int] = COMM_SET_RPM
    erpm: float

    def to_payload(self) -> bytes:
        return bytes([self.CMD]) + struct.pack(">i", round(self.erpm))


# §3.4: (name, struct format, scale) in payload order after the command id
_VALUES = (("temp_fet_c", "h", 10.0), ("temp_motor_c", "h", 10.0),
           ("motor_current_a", "i", 100.0), ("input_current_a", "i", 100.0),
           ("id_a", "i", 100.0), ("iq_a", "i", 100.0), ("duty", "h", 1000.0),
           ("erpm", "i", 1.0), ("voltage_in_v", "h", 10.0), ("amp_hours", "i", 1e4),
           ("amp_hours_charged", "i", 1e4), ("watt_hours", "i", 1e4),
           ("watt_hours_charged", "i", 1e4), ("tachometer", "i", 1.0),
           ("tachometer_abs", "i", 1.0), ("fault_code", "B", 1.0))
_MIN_VALUES = 1 + struct.calcsize(">" + "".join(f for _, f, _ in _VALUES[:9]))  # up to V_in


@dataclass(frozen=True)
class Values:
    """``GET_VALUES`` reply (§3.4), SI; fields an older firmware leaves out are None.

    The bench needs up to ``voltage_in_v`` (29 payload bytes); the rest is read when there.
    """

    CMD: ClassVar[int] = COMM_GET_VALUES
    temp_fet_c: float
    temp_motor_c: float
    motor_current_a: float
    input_current_a: float
    id_a: float
    iq_a: float
    duty: float
    erpm: float
    voltage_in_v: float
    amp_hours: float | None = None
    amp_hours_charged: float | None = None
    watt_hours: float | None = None
    watt_hours_charged: float | None = None
    tachometer: float | None = None
    tachometer_abs: float | None = None
    fault_code: float | None = None
    controller_id: int | None = None
    timeout_active: bool | None = None

    def to_payload(self) -> bytes:
        """The full 74-byte payload of current firmware (§3.4); absent fields as 0."""
        out = bytearray([self.CMD])
        for name, fmt, scale in _VALUES:
            v = getattr(self, name) or 0.0
            out += struct.pack(">" + fmt, round(v * scale))
        out += struct.pack(">i", 0)  # PID position
        out += bytes([self.controller_id or 0])
        out += struct.pack(">3h", *(round(self.temp_fet_c * 10),) * 3)  # MOSFET temps
        out += struct.pack(">ii", 0, 0)  # vd, vq
        out += bytes([1 if self.timeout_active else 0])
        return bytes(out)

    @classmethod
    def from_payload(cls, p: bytes) -> Values:
        if len(p) < _MIN_VALUES:
            raise PayloadError(f"GET_VALUES payload of {len(p)} bytes, expected at least "
                               f"{_MIN_VALUES}")
        kw: dict[str, object] = {}
        at = 1
        for name, fmt, scale in _VALUES:
            size = struct.calcsize(fmt)
            if at + size > len(p):
                break
            (raw,) = struct.unpack_from(">" + fmt, p, at)
            kw[name] = raw / scale
            at += size
        if len(p) >= 59:  # PID position at 54..57, controller id at 58
            kw["controller_id"] = p[58]
        if len(p) >= 74:
            kw["timeout_active"] = bool(p[73] & 1)
        return cls(**kw)  # type: ignore[arg-type]


@dataclass(frozen=True)
class Unknown:
    """A valid packet of a command this codec does not interpret."""

    cmd: int
    payload_hex: str


VescUartMessage = Request | SetDuty | SetCurrent | SetCurrentBrake | SetRpm | Values | Unknown
_SETS = {c.CMD: c for c in (SetDuty, SetCurrent, SetCurrentBrake, SetRpm)}


def encode(msg: VescUartMessage) -> bytes:
    if isinstance(msg, Unknown):
        return frame(bytes.fromhex(msg.payload_hex))
    return frame(msg.to_payload())


def parse(payload: bytes, *, replies: bool) -> VescUartMessage:
    """Typed message of a packet payload; ``replies`` picks the direction (a host's
    GET_VALUES request and the VESC's reply share the command id)."""
    cmd = payload[0]
    if replies and cmd == COMM_GET_VALUES:
        return Values.from_payload(payload)
    if not replies and cmd in _SETS:
        if len(payload) != 5:
            raise PayloadError(f"command {cmd}: payload of {len(payload)} bytes, expected 5")
        (raw,) = struct.unpack_from(">i", payload, 1)
        scale = {COMM_SET_DUTY: 1e5, COMM_SET_RPM: 1.0}.get(cmd, 1e3)
        return _SETS[cmd](raw / scale)
    if not replies and len(payload) == 1:
        return Request(cmd)
    return Unknown(cmd, payload.hex())


class VescUartDecoder(FrameDecoder):
    """Resynchronising decoder of VESC packets; ``replies=True`` for the VESC's side of
    the conversation, False for the host's. Yields typed messages (``parse``)."""

    sync = re.compile(rb"[\x02\x03]")

    def __init__(self, *, replies: bool, max_payload: int = MAX_PAYLOAD) -> None:
        super().__init__()
        self.replies = replies
        self.max_payload = max_payload

    def try_frame(self, buf: bytes | bytearray, i: int) -> Attempt:
        n = len(buf) - i
        long = buf[i] == 3
        hdr = 3 if long else 2
        if n < hdr:
            return NEED_HEADER
        size = struct.unpack_from(">H", buf, i + 1)[0] if long else buf[i + 1]
        if size == 0 or size > self.max_payload or (long and size <= 0xFF):
            return NOT_A_FRAME
        total = hdr + size + 3
        if n < total:
            return NEED_BODY
        if buf[i + total - 1] != 3:
            return NOT_A_FRAME
        payload = bytes(buf[i + hdr:i + hdr + size])
        if struct.unpack_from(">H", buf, i + hdr + size)[0] != crc16_xmodem(payload):
            return Attempt(Status.BAD_CHECKSUM, total)
        try:
            return Attempt(Status.OK, total, parse(payload, replies=self.replies))
        except PayloadError:
            return Attempt(Status.MALFORMED, total)
