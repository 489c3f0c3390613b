"""Checksums and CRCs of the bench protocols, each with where protocols.md defines it.

The two CRC-16 variants with polynomial 0x1021, no reflection (XMODEM, init 0 and
CCITT-FALSE, init 0xFFFF) are the standard library's ``binascii.crc_hqx`` with that init.
"""

from __future__ import annotations

import binascii


def _crc8_table(poly: int) -> tuple[int, ...]:
    table = []
    for byte in range(256):
        crc = byte
        for _ in range(8):
            crc = ((crc << 1) ^ poly) & 0xFF if crc & 0x80 else (crc << 1) & 0xFF
        table.append(crc)
    return tuple(table)


# protocols.md §1.2: CRC8 DVB-S2, poly 0xD5, init 0, MSB-first, no reflection, no xorout.
_DVB_S2 = _crc8_table(0xD5)


def crc8_dvb_s2(data: bytes | bytearray | memoryview, crc: int = 0) -> int:
    """MSP v2 CRC (protocols.md §1.2); check value of b"123456789" is 0xBC."""
    for b in data:
        crc = _DVB_S2[crc ^ b]
    return crc


def xor8(data: bytes | bytearray | memoryview) -> int:
    """MSP v1 checksum: XOR of size, cmd and payload bytes (protocols.md §1.1)."""
    acc = 0
    for b in data:
        acc ^= b
    return acc


def sum16(data: bytes | bytearray | memoryview) -> int:
    """3DM-GX3 checksum: 16-bit unsigned sum of the reply bytes (protocols.md §2.1)."""
    return sum(data) & 0xFFFF


def crc16_ccitt_false(data: bytes | bytearray, crc: int = 0xFFFF) -> int:
    """UAVCAN v0 transfer CRC: CRC-16-CCITT-FALSE, poly 0x1021, init 0xFFFF (§4.2)."""
    return binascii.crc_hqx(bytes(data), crc)


def crc16_xmodem(data: bytes | bytearray) -> int:
    """VESC UART packet CRC: CRC-16/XMODEM, poly 0x1021, init 0 (protocols.md §3.3)."""
    return binascii.crc_hqx(bytes(data), 0)
