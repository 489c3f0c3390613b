"""KISS / BLHeli_32 ESC serial telemetry: 10-byte frames of temperature, volts, amps, speed.

The ESC sends one frame per request (a DShot telemetry bit, or continuously on some
firmware) on a one-wire UART at 115 200 baud (docs/protocols.md, "KISS / BLHeli_32 ESC
telemetry"; Betaflight ``src/main/sensors/esc_sensor.c``):

====  ===========================================  ==========
byte  field                                        unit
====  ===========================================  ==========
0     temperature                                  °C (uint8)
1-2   voltage                                      0.01 V
3-4   current                                      0.01 A
5-6   consumption                                  mAh
7-8   electrical speed                             100 eRPM
9     CRC8 of bytes 0-8                            -
====  ===========================================  ==========

Words are big-endian uint16. The CRC is Betaflight's ``calculateCrc8``/``updateCrc8``
(KISS's ``get_crc8``/``update_crc8``): polynomial 0x07, init 0, MSB first, no reflection,
no final XOR (CRC-8/SMBUS; check value of ``b"123456789"`` is 0xF4). The frame has no
start byte: :class:`KissDecoder` tries every offset and keeps the 10 bytes whose CRC
holds, so it resynchronises by itself after a lost byte and counts the CRC failures. A
random 10-byte window passes the CRC one time in 256, which is why the backend keeps the
stream aligned and the host may cross-check values (a frame that decodes is not proof).
"""

from __future__ import annotations

import re
import struct
from dataclasses import dataclass

from drivers.codecs.stream import NEED_HEADER, Attempt, FrameDecoder, Status

FRAME_LEN = 10
BAUD = 115_200  # ESC_SENSOR_BAUDRATE
_WORDS = struct.Struct(">BHHHH")


def _crc8_table() -> tuple[int, ...]:
    table = []
    for byte in range(256):
        crc = byte
        for _ in range(8):
            crc = ((crc << 1) ^ 0x07) & 0xFF if crc & 0x80 else (crc << 1) & 0xFF
        table.append(crc)
    return tuple(table)


_TABLE = _crc8_table()


def crc8(data: bytes | bytearray | memoryview, crc: int = 0) -> int:
    """KISS/BLHeli_32 telemetry CRC8 (poly 0x07, init 0, MSB first)."""
    for b in data:
        crc = _TABLE[crc ^ b]
    return crc


@dataclass(frozen=True)
class Telemetry:
    """One frame in SI units (``erpm`` is electrical revolutions per minute)."""

    temperature_c: float
    voltage_v: float
    current_a: float
    consumption_mah: float
    erpm: float

    def rpm(self, pole_pairs: int) -> float:
        """Mechanical speed: eRPM over the motor's pole pairs (Betaflight calcEscRpm)."""
        return self.erpm / pole_pairs


def encode(t: Telemetry) -> bytes:
    """The 10 bytes of a frame; values are rounded and clamped to the wire's range."""
    def word(x: float, scale: float) -> int:
        return min(0xFFFF, max(0, round(x * scale)))

    body = _WORDS.pack(min(0xFF, max(0, round(t.temperature_c))), word(t.voltage_v, 100),
                       word(t.current_a, 100), word(t.consumption_mah, 1),
                       word(t.erpm, 0.01))
    return body + bytes([crc8(body)])


def decode_frame(frame: bytes | bytearray) -> Telemetry:
    """One frame's fields (the CRC is checked by the caller, see :class:`KissDecoder`)."""
    temp, volt, cur, mah, erpm = _WORDS.unpack(bytes(frame[:9]))
    return Telemetry(float(temp), volt / 100.0, cur / 100.0, float(mah), erpm * 100.0)


class KissDecoder(FrameDecoder[Telemetry]):
    """Frames from a byte stream: any offset may start one; its CRC decides."""

    sync = re.compile(b".", re.S)

    def try_frame(self, buf: bytes | bytearray, start: int) -> Attempt[Telemetry]:
        if len(buf) - start < FRAME_LEN:  # no header to judge: not a truncated frame yet
            return NEED_HEADER
        frame = buf[start:start + FRAME_LEN]
        if crc8(frame[:9]) != frame[9]:
            return Attempt(Status.BAD_CHECKSUM, FRAME_LEN)
        return Attempt(Status.OK, FRAME_LEN, decode_frame(frame))
