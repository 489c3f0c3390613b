"""VESC (bldc firmware) on CAN: control commands and status broadcasts.

Extended 29-bit id = ``(packet_id << 8) | controller_id``; payloads are big-endian
integers scaled by fixed factors. Facts: protocols.md §3.1-§3.2 (``vedderb/bldc``
``comm/comm_can.c``, ``datatypes.h``, ``util/buffer.c``). Messages carry SI values (duty
as a fraction -1..1, amperes, volts, °C); speeds are *electrical* rpm as the VESC sends
them — mechanical rpm needs the motor's pole pairs (``mech_rpm``).

The VESC releases the motor when no control command arrives for
``COMMAND_TIMEOUT_S`` (§3.2 ``APPCONF_TIMEOUT_MSEC 1000``): a driver repeats the last
command well inside that time.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass

from drivers.codecs.can_log import CanFrame, CanStats

COMMAND_TIMEOUT_S = 1.0  # §3.2 APPCONF_TIMEOUT_MSEC 1000
BITRATE = 500_000  # §3.2 APPCONF_CAN_BAUD_RATE CAN_BAUD_500K

# §3.2 CAN_PACKET_* ids
SET_DUTY = 0
SET_CURRENT = 1
SET_CURRENT_BRAKE = 2
SET_RPM = 3
SET_POS = 4
STATUS_1 = 9
SET_CURRENT_REL = 10
STATUS_2 = 14
STATUS_3 = 15
STATUS_4 = 16
PING = 17
PONG = 18
STATUS_5 = 27
STATUS_6 = 58


def can_id(packet_id: int, controller_id: int) -> int:
    """§3.2: ``(packet_id << 8) | controller_id``."""
    if not 0 <= controller_id <= 0xFF or not 0 <= packet_id <= 0x1FFFFF:
        raise ValueError(f"VESC ids out of range: packet {packet_id}, controller {controller_id}")
    return packet_id << 8 | controller_id


def split_id(arbitration_id: int) -> tuple[int, int]:
    """(packet_id, controller_id) of an extended id (§3.2 decoder: ``cmd = eid >> 8``)."""
    return arbitration_id >> 8, arbitration_id & 0xFF


def mech_rpm(erpm: float, pole_pairs: int) -> float:
    """Mechanical rpm from electrical rpm (§3.2: ERPM = mech rpm × pole pairs)."""
    return erpm / pole_pairs


def _i32(x: float) -> int:
    v = round(x)
    if not -(2**31) <= v < 2**31:
        raise ValueError(f"{x} does not fit an int32 field")
    return v


def _i16(x: float) -> int:
    v = round(x)
    if not -(2**15) <= v < 2**15:
        raise ValueError(f"{x} does not fit an int16 field")
    return v


@dataclass(frozen=True)
class SetDuty:
    """§3.2 SET_DUTY: int32 duty·100000."""

    controller_id: int
    duty: float


@dataclass(frozen=True)
class SetCurrent:
    """§3.2 SET_CURRENT: int32 A·1000 [+ int16 off-delay·1000 when 6 bytes]."""

    controller_id: int
    current_a: float
    off_delay_s: float | None = None


@dataclass(frozen=True)
class SetCurrentBrake:
    """§3.2 SET_CURRENT_BRAKE: int32 A·1000."""

    controller_id: int
    current_a: float


@dataclass(frozen=True)
class SetRpm:
    """§3.2 SET_RPM: int32 electrical rpm."""

    controller_id: int
    erpm: float


@dataclass(frozen=True)
class Status1:
    """§3.2 STATUS: int32 ERPM, int16 motor current·10, int16 duty·1000."""

    controller_id: int
    erpm: float
    current_a: float
    duty: float


@dataclass(frozen=True)
class Status2:
    """§3.2 STATUS_2: int32 Ah·1e4, int32 Ah charged·1e4."""

    controller_id: int
    amp_hours: float
    amp_hours_charged: float


@dataclass(frozen=True)
class Status3:
    """§3.2 STATUS_3: int32 Wh·1e4, int32 Wh charged·1e4."""

    controller_id: int
    watt_hours: float
    watt_hours_charged: float


@dataclass(frozen=True)
class Status4:
    """§3.2 STATUS_4: int16 T_fet·10, T_motor·10 (°C), I_in·10 (A), pid_pos·50."""

    controller_id: int
    temp_fet_c: float
    temp_motor_c: float
    current_in_a: float
    pid_pos: float


@dataclass(frozen=True)
class Status5:
    """§3.2 STATUS_5: int32 tachometer, int16 V_in·10, int16 reserved."""

    controller_id: int
    tachometer: int
    voltage_in_v: float


@dataclass(frozen=True)
class Status6:
    """§3.2 STATUS_6: int16 ADC1, ADC2, ADC3 (V) and PPM, each ·1000."""

    controller_id: int
    adc1_v: float
    adc2_v: float
    adc3_v: float
    ppm: float


@dataclass(frozen=True)
class Unknown:
    """A VESC-shaped frame of a packet id this codec does not interpret."""

    packet_id: int
    controller_id: int
    data_hex: str


VescMessage = (SetDuty | SetCurrent | SetCurrentBrake | SetRpm | Status1 | Status2 | Status3
               | Status4 | Status5 | Status6 | Unknown)

# (packet id, struct format, scale per field) for the fixed-layout messages; scales §3.2.
_LAYOUT: dict[type, tuple[int, str, tuple[float, ...]]] = {
    SetDuty: (SET_DUTY, ">i", (1e5,)),
    SetCurrentBrake: (SET_CURRENT_BRAKE, ">i", (1e3,)),
    SetRpm: (SET_RPM, ">i", (1.0,)),
    Status1: (STATUS_1, ">ihh", (1.0, 10.0, 1000.0)),
    Status2: (STATUS_2, ">ii", (1e4, 1e4)),
    Status3: (STATUS_3, ">ii", (1e4, 1e4)),
    Status4: (STATUS_4, ">hhhh", (10.0, 10.0, 10.0, 50.0)),
    Status6: (STATUS_6, ">hhhh", (1e3, 1e3, 1e3, 1e3)),
}
_BY_ID = {pid: (cls, fmt, scales) for cls, (pid, fmt, scales) in _LAYOUT.items()}


def encode(msg: VescMessage) -> CanFrame:
    """The CAN frame of a message (commands from the host, status from the VESC)."""
    if isinstance(msg, Unknown):
        return CanFrame(can_id(msg.packet_id, msg.controller_id), bytes.fromhex(msg.data_hex))
    if isinstance(msg, SetCurrent):
        data = struct.pack(">i", _i32(msg.current_a * 1e3))
        if msg.off_delay_s is not None:
            data += struct.pack(">h", _i16(msg.off_delay_s * 1e3))
        return CanFrame(can_id(SET_CURRENT, msg.controller_id), data)
    if isinstance(msg, Status5):
        data = struct.pack(">ihh", _i32(msg.tachometer), _i16(msg.voltage_in_v * 10), 0)
        return CanFrame(can_id(STATUS_5, msg.controller_id), data)
    pid, fmt, scales = _LAYOUT[type(msg)]
    values = [getattr(msg, f) for f in msg.__dataclass_fields__][1:]
    ints = [(_i32 if c == "i" else _i16)(v * s) for v, s, c in zip(values, scales, fmt[1:],
                                                                    strict=True)]
    return CanFrame(can_id(pid, msg.controller_id), struct.pack(fmt, *ints))


def decode(frame: CanFrame) -> VescMessage | None:
    """Message of a frame; ``None`` when the frame cannot be VESC (standard id or a
    known packet with the wrong length)."""
    if not frame.is_extended_id:
        return None
    pid, ctrl = split_id(frame.arbitration_id)
    data = frame.data
    if pid == SET_CURRENT:
        if len(data) == 4:
            return SetCurrent(ctrl, struct.unpack(">i", data)[0] / 1e3)
        if len(data) >= 6:  # §3.2 optional off-delay when len >= 6
            cur, delay = struct.unpack_from(">ih", data)
            return SetCurrent(ctrl, cur / 1e3, delay / 1e3)
        return None
    if pid == STATUS_5:
        if len(data) != 8:
            return None
        tacho, vin, _ = struct.unpack(">ihh", data)
        return Status5(ctrl, tacho, vin / 10)
    if pid in _BY_ID:
        cls, fmt, scales = _BY_ID[pid]
        if len(data) != struct.calcsize(fmt):
            return None
        ints = struct.unpack(fmt, data)
        return cls(ctrl, *(v / s for v, s in zip(ints, scales, strict=True)))
    return Unknown(pid, ctrl, data.hex())


class VescDecoder:
    """Counts what ``decode`` drops on a stream of frames; never raises on bad frames.

    ``controller_ids`` (optional) keeps only the given VESCs; others count as foreign.
    """

    def __init__(self, controller_ids: set[int] | None = None) -> None:
        self.controller_ids = controller_ids
        self.stats = CanStats()

    def feed(self, frame: CanFrame) -> list[VescMessage]:
        self.stats.frames_in += 1
        if not frame.is_extended_id or (
                self.controller_ids is not None
                and split_id(frame.arbitration_id)[1] not in self.controller_ids):
            self.stats.foreign += 1
            return []
        msg = decode(frame)
        if msg is None:
            self.stats.malformed += 1
            return []
        self.stats.messages += 1
        return [msg]
