"""DroneCAN (UAVCAN v0) ESC messages on CAN: RawCommand, Status, NodeStatus.

Transport (protocols.md §4.2, from pydronecan ``transport.py``, checked by the reference
against dronecan 1.0.27): 29-bit id = priority (bits 28-24) · data type id (23-8) ·
service flag (bit 7, 0 for messages) · source node (6-0). The last data byte of every
frame is the tail byte (start, end, toggle, 5-bit transfer id). Payloads longer than 7
bytes travel in several frames whose first two bytes are a CRC-16-CCITT-FALSE over the
data type signature (8 bytes LE) and the payload. Fields are bit-packed MSB-first, each
N-bit field written little-endian with the last partial byte left-aligned (libcanard).

Definitions: §4.1 (``dronecan/DSDL``). Status temperature is in kelvin on the wire and
stays in kelvin here (``temperature_k``); unknown float fields are NaN.
"""

from __future__ import annotations

import math
import struct
from dataclasses import dataclass

from drivers.codecs.can_log import CanFrame, CanStats
from drivers.codecs.checksums import crc16_ccitt_false

# §4.1 data type ids and signatures
RAW_COMMAND_DTID = 1030
RAW_COMMAND_SIGNATURE = 0x217F5C87D7EC951D
STATUS_DTID = 1034
STATUS_SIGNATURE = 0xA9AF28AEA2FBB254
NODE_STATUS_DTID = 341  # single frame (7 bytes), so its signature is never needed

DEFAULT_PRIORITY = 16  # §4.2 pydronecan default
BITRATE = 1_000_000  # §4.2 conventional bus bitrate
RAW_MIN, RAW_MAX = -8192, 8191  # §4.1 int14 normalised command
RAW_MAX_ESCS = 20  # §4.1 int14[<=20]
MAX_TRANSFER_BYTES = 64  # decoder guard, above every payload handled here

_SOT, _EOT, _TOGGLE = 0x80, 0x40, 0x20  # §4.2 tail byte bits 7, 6, 5


# ---------------------------------------------------------------------------- bit packing


class BitWriter:
    """libcanard bit packing (§4.2): MSB-first stream, N-bit fields little-endian."""

    def __init__(self) -> None:
        self._acc = 0
        self._nbits = 0

    def _put(self, value: int, nbits: int) -> None:
        self._acc = (self._acc << nbits) | (value & ((1 << nbits) - 1))
        self._nbits += nbits

    def write(self, value: int, nbits: int, *, signed: bool = False) -> None:
        lo, hi = (-(1 << (nbits - 1)), (1 << (nbits - 1)) - 1) if signed else (0, (1 << nbits) - 1)
        if not lo <= value <= hi:
            raise ValueError(f"{value} does not fit a {'signed' if signed else 'unsigned'} "
                             f"{nbits}-bit field")
        u = value & ((1 << nbits) - 1)
        full, rest = divmod(nbits, 8)
        for k in range(full):
            self._put(u >> (8 * k), 8)
        if rest:
            self._put(u >> (8 * full), rest)

    def write_f16(self, value: float) -> None:
        try:
            raw = struct.unpack("<H", struct.pack("<e", value))[0]
        except OverflowError:
            raise ValueError(f"{value} does not fit a float16 field") from None
        self.write(raw, 16)

    def to_bytes(self) -> bytes:
        pad = -self._nbits % 8
        return ((self._acc << pad).to_bytes((self._nbits + pad) // 8, "big")
                if self._nbits else b"")


class BitReader:
    """Reads fields written by ``BitWriter`` (raises ``ValueError`` past the end)."""

    def __init__(self, data: bytes) -> None:
        self._acc = int.from_bytes(data, "big")
        self._total = len(data) * 8
        self._pos = 0

    @property
    def remaining(self) -> int:
        return self._total - self._pos

    def _get(self, nbits: int) -> int:
        if nbits > self.remaining:
            raise ValueError("payload too short")
        self._pos += nbits
        return (self._acc >> (self._total - self._pos)) & ((1 << nbits) - 1)

    def read(self, nbits: int, *, signed: bool = False) -> int:
        full, rest = divmod(nbits, 8)
        u = 0
        for k in range(full):
            u |= self._get(8) << (8 * k)
        if rest:
            u |= self._get(rest) << (8 * full)
        if signed and u >> (nbits - 1):
            u -= 1 << nbits
        return u

    def read_f16(self) -> float:
        return struct.unpack("<e", struct.pack("<H", self.read(16)))[0]


# ---------------------------------------------------------------------------- messages


@dataclass(frozen=True)
class RawCommand:
    """uavcan.equipment.esc.RawCommand (§4.1): int14 per ESC, -8192..8191, 0 = stop."""

    cmd: tuple[int, ...]

    DTID = RAW_COMMAND_DTID

    def to_payload(self) -> bytes:
        if len(self.cmd) > RAW_MAX_ESCS:
            raise ValueError(f"RawCommand holds at most {RAW_MAX_ESCS} ESCs, got {len(self.cmd)}")
        w = BitWriter()
        for c in self.cmd:  # tail array: no length prefix (§4.2)
            w.write(int(c), 14, signed=True)
        return w.to_bytes()

    @classmethod
    def from_payload(cls, p: bytes) -> RawCommand:
        n = len(p) * 8 // 14
        if n > RAW_MAX_ESCS or len(p) != math.ceil(n * 14 / 8):
            raise ValueError(f"RawCommand payload of {len(p)} bytes is not a whole int14 array")
        r = BitReader(p)
        return cls(tuple(r.read(14, signed=True) for _ in range(n)))


def raw_from_fraction(x: float) -> int:
    """Command -1..1 -> the normalised int14 range of §4.1 (clamped)."""
    return max(RAW_MIN, min(RAW_MAX, round(x * (RAW_MAX if x >= 0 else -RAW_MIN))))


@dataclass(frozen=True)
class EscStatus:
    """uavcan.equipment.esc.Status (§4.1), 110 bits in 14 bytes."""

    error_count: int
    voltage_v: float
    current_a: float
    temperature_k: float
    rpm: int
    power_rating_pct: int
    esc_index: int

    DTID = STATUS_DTID

    def to_payload(self) -> bytes:
        w = BitWriter()
        w.write(self.error_count, 32)
        w.write_f16(self.voltage_v)
        w.write_f16(self.current_a)
        w.write_f16(self.temperature_k)
        w.write(self.rpm, 18, signed=True)
        w.write(self.power_rating_pct, 7)
        w.write(self.esc_index, 5)
        return w.to_bytes()

    @classmethod
    def from_payload(cls, p: bytes) -> EscStatus:
        if len(p) != 14:
            raise ValueError(f"ESC Status payload must be 14 bytes, got {len(p)}")
        r = BitReader(p)
        return cls(r.read(32), r.read_f16(), r.read_f16(), r.read_f16(), r.read(18, signed=True),
                   r.read(7), r.read(5))


@dataclass(frozen=True)
class NodeStatus:
    """uavcan.protocol.NodeStatus (§4.1): uptime, health, mode, sub-mode, vendor code."""

    uptime_sec: int
    health: int
    mode: int
    sub_mode: int
    vendor_specific_status_code: int

    DTID = NODE_STATUS_DTID

    def to_payload(self) -> bytes:
        w = BitWriter()
        w.write(self.uptime_sec, 32)
        w.write(self.health, 2)
        w.write(self.mode, 3)
        w.write(self.sub_mode, 3)
        w.write(self.vendor_specific_status_code, 16)
        return w.to_bytes()

    @classmethod
    def from_payload(cls, p: bytes) -> NodeStatus:
        if len(p) != 7:
            raise ValueError(f"NodeStatus payload must be 7 bytes, got {len(p)}")
        r = BitReader(p)
        return cls(r.read(32), r.read(2), r.read(3), r.read(3), r.read(16))


@dataclass(frozen=True)
class Unknown:
    """A single-frame message of a data type this codec does not interpret."""

    data_type_id: int
    payload_hex: str


#: The messages this codec interprets (each knows its data type id, ``DTID``).
KnownMessage = RawCommand | EscStatus | NodeStatus
DroneCanMessage = KnownMessage | Unknown

_TYPES: dict[int, type] = {RAW_COMMAND_DTID: RawCommand, STATUS_DTID: EscStatus,
                           NODE_STATUS_DTID: NodeStatus}
_SIGNATURES: dict[int, int] = {RAW_COMMAND_DTID: RAW_COMMAND_SIGNATURE,
                               STATUS_DTID: STATUS_SIGNATURE}


# ---------------------------------------------------------------------------- transport


@dataclass(frozen=True)
class MessageId:
    """Fields of a message-frame CAN id (§4.2)."""

    priority: int
    data_type_id: int
    source_node_id: int

    def to_int(self) -> int:
        if not (0 <= self.priority < 32 and 0 <= self.data_type_id < 1 << 16
                and 0 <= self.source_node_id < 128):
            raise ValueError(f"DroneCAN id fields out of range: {self}")
        return self.priority << 24 | self.data_type_id << 8 | self.source_node_id

    @classmethod
    def from_int(cls, can_id: int) -> MessageId | None:
        """``None`` for service frames (bit 7 set), which this codec does not handle."""
        if can_id & 0x80:
            return None
        return cls(can_id >> 24 & 0x1F, can_id >> 8 & 0xFFFF, can_id & 0x7F)


def transfer_crc(signature: int, payload: bytes) -> int:
    """§4.2: CRC-16-CCITT-FALSE over the signature (8 bytes LE) then the payload."""
    return crc16_ccitt_false(signature.to_bytes(8, "little") + payload)


def encode(msg: DroneCanMessage, source_node_id: int, transfer_id: int,
           priority: int = DEFAULT_PRIORITY, timestamp: float = 0.0) -> list[CanFrame]:
    """The frames of one message transfer (§4.2)."""
    if isinstance(msg, Unknown):
        dtid, payload = msg.data_type_id, bytes.fromhex(msg.payload_hex)
    else:
        dtid, payload = msg.DTID, msg.to_payload()
    ident = MessageId(priority, dtid, source_node_id).to_int()
    tid = transfer_id & 0x1F
    if len(payload) <= 7:
        return [CanFrame(ident, payload + bytes([_SOT | _EOT | tid]), timestamp=timestamp)]
    if dtid not in _SIGNATURES:
        raise ValueError(f"multi-frame transfer of data type {dtid} needs its signature")
    data = transfer_crc(_SIGNATURES[dtid], payload).to_bytes(2, "little") + payload
    chunks = [data[k : k + 7] for k in range(0, len(data), 7)]
    frames = []
    for k, chunk in enumerate(chunks):
        tail = tid | (_TOGGLE if k % 2 else 0)
        tail |= _SOT if k == 0 else 0
        tail |= _EOT if k == len(chunks) - 1 else 0
        frames.append(CanFrame(ident, chunk + bytes([tail]), timestamp=timestamp))
    return frames


@dataclass(frozen=True)
class Received:
    """A decoded message with its transfer metadata."""

    source_node_id: int
    priority: int
    transfer_id: int
    timestamp: float
    message: DroneCanMessage


@dataclass
class _Partial:
    transfer_id: int
    crc: int
    toggle: int
    data: bytearray
    priority: int
    timestamp: float


class DroneCanDecoder:
    """Reassembles transfers from frames (one in flight per source node and data type).

    Never raises on bad frames: foreign ids, impossible layouts, failed CRCs, transfers
    cut short by a new start and continuation frames without a start are counted in
    ``stats`` and dropped. A repeated frame (wrong toggle) is ignored.
    """

    def __init__(self) -> None:
        self.stats = CanStats()
        self._partial: dict[tuple[int, int], _Partial] = {}

    def feed(self, frame: CanFrame) -> list[Received]:
        st = self.stats
        st.frames_in += 1
        mid = MessageId.from_int(frame.arbitration_id) if frame.is_extended_id else None
        if mid is None or not frame.data:
            st.foreign += 1
            return []
        tail, body = frame.data[-1], frame.data[:-1]
        sot, eot, toggle, tid = tail & _SOT, tail & _EOT, int(bool(tail & _TOGGLE)), tail & 0x1F
        key = (mid.source_node_id, mid.data_type_id)
        if sot:
            if key in self._partial:
                del self._partial[key]
                st.truncated += 1
            if toggle:
                st.malformed += 1
                return []
            if eot:
                return self._complete(mid, tid, frame.timestamp, bytes(body))
            if mid.data_type_id not in _SIGNATURES:
                st.foreign += 1
                return []
            if len(body) < 3:
                st.malformed += 1
                return []
            crc = body[0] | body[1] << 8
            self._partial[key] = _Partial(tid, crc, 1, bytearray(body[2:]), mid.priority,
                                          frame.timestamp)
            return []
        part = self._partial.get(key)
        if part is None or part.transfer_id != tid or part.toggle != toggle:
            st.orphan_frames += 1
            return []
        part.data += body
        part.toggle ^= 1
        if len(part.data) > MAX_TRANSFER_BYTES:
            del self._partial[key]
            st.malformed += 1
            return []
        if not eot:
            return []
        del self._partial[key]
        payload = bytes(part.data)
        if transfer_crc(_SIGNATURES[mid.data_type_id], payload) != part.crc:
            st.bad_crc += 1
            return []
        return self._complete(mid, tid, part.timestamp, payload)

    def _complete(self, mid: MessageId, tid: int, ts: float, payload: bytes) -> list[Received]:
        cls = _TYPES.get(mid.data_type_id)
        try:
            msg = cls.from_payload(payload) if cls else Unknown(mid.data_type_id, payload.hex())
        except ValueError:
            self.stats.malformed += 1
            return []
        self.stats.messages += 1
        return [Received(mid.source_node_id, mid.priority, tid, ts, msg)]

    def flush(self) -> list[Received]:
        """End of the log: transfers still in flight count as truncated."""
        self.stats.truncated += len(self._partial)
        self._partial.clear()
        return []
