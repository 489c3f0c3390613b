"""CAN frames as plain data, and candump-style text logs of them.

The CAN codecs (VESC, DroneCAN) are pure functions on ``CanFrame``; a backend converts
to and from ``can.Message`` at its edge, so the codecs do not need python-can.

Two candump log shapes are read (protocols.md §9 names python-can's ``canutils`` log,
which is ``candump -L``):

* ``candump -L`` / python-can ``.log``: ``(1700000000.123456) can0 00000901#00002EE0006900FA``
  (ids of more than 3 hex digits are extended, as in python-can's ``CanutilsLogReader``);
* the default ``candump`` screen form: ``  can0  00000901   [8]  00 00 2E E0 00 69 00 FA``.

Empty lines and lines starting with ``#`` are ignored, and so are remote (RTR) frames, CAN FD
frames (``##``) and error frames (id with ``CAN_ERR_FLAG``), which the bench protocols never use.
"""

from __future__ import annotations

import re
from collections.abc import Iterable, Iterator
from dataclasses import asdict, dataclass

from drivers.errors import DeviceError


@dataclass(frozen=True)
class CanFrame:
    """One classic CAN data frame (the bench protocols use 29-bit extended ids)."""

    arbitration_id: int
    data: bytes
    is_extended_id: bool = True
    timestamp: float = 0.0
    channel: str = ""

    def __post_init__(self) -> None:
        limit = 0x1FFFFFFF if self.is_extended_id else 0x7FF
        if not 0 <= self.arbitration_id <= limit:
            raise ValueError(f"CAN id 0x{self.arbitration_id:X} out of range")
        if len(self.data) > 8:
            raise ValueError(f"classic CAN frames carry at most 8 bytes, got {len(self.data)}")


@dataclass
class CanStats:
    """Counters of a CAN decoder: frames seen, messages out, and what was dropped.

    ``foreign``: frames of other protocols/ids; ``malformed``: frames of the protocol with
    an impossible length or layout; ``bad_crc``/``truncated``/``orphan_frames``: multi-frame
    transfers with a failed CRC, cut short by a new start, or continuation frames without a
    start (DroneCAN).
    """

    frames_in: int = 0
    messages: int = 0
    foreign: int = 0
    malformed: int = 0
    bad_crc: int = 0
    truncated: int = 0
    orphan_frames: int = 0

    def as_dict(self) -> dict[str, int]:
        return asdict(self)


class CanLogError(DeviceError):
    """A candump-style log line could not be read; names the file and line."""


CAN_ERR_FLAG = 0x20000000  # SocketCAN error-frame flag in candump ids (python-can canutils)
_REMOTE_OR_FD = re.compile(r"^(?:\([0-9.]+\)\s+)?\S+\s+[0-9A-Fa-f]{1,8}#(?:#|[Rr])")
_LOG_L = re.compile(r"^\((?P<ts>[0-9.]+)\)\s+(?P<ch>\S+)\s+(?P<id>[0-9A-Fa-f]{1,8})#"
                    r"(?P<data>[0-9A-Fa-f]*)(?:\s+[RrTt])?$")
_LOG_SCREEN = re.compile(r"^(?:\((?P<ts>[0-9.]+)\)\s+)?(?P<ch>\S+)\s+(?P<id>[0-9A-Fa-f]{1,8})\s+"
                         r"\[(?P<dlc>\d)\]\s*(?P<data>(?:[0-9A-Fa-f]{2}\s*)*)$")


def parse_line(line: str, *, source: str = "<log>", lineno: int = 0) -> CanFrame | None:
    """One log line -> frame; ``None`` for blank and comment lines."""
    text = line.strip()
    if not text or text.startswith("#"):
        return None
    if _REMOTE_OR_FD.match(text):
        return None  # remote (RTR) and CAN FD frames carry no classic-CAN payload here
    m = _LOG_L.match(text)
    if m is not None:
        data_hex = m["data"]
        if len(data_hex) % 2:
            raise CanLogError(f"{source}:{lineno}: odd number of hex digits in data {data_hex!r}")
    else:
        m = _LOG_SCREEN.match(text)
        if m is None:
            raise CanLogError(f"{source}:{lineno}: not a candump line "
                              f"(expected '(time) can0 1ABCDE01#0011..' or "
                              f"'can0 1ABCDE01 [2] 00 11'): {text[:60]!r}")
        data_hex = re.sub(r"\s+", "", m["data"])
        if len(data_hex) // 2 != int(m["dlc"]):
            raise CanLogError(f"{source}:{lineno}: [{m['dlc']}] bytes announced, "
                              f"{len(data_hex) // 2} given")
    data = bytes.fromhex(data_hex)
    if len(data) > 8:
        raise CanLogError(f"{source}:{lineno}: {len(data)} data bytes, classic CAN allows 8")
    ident = m["id"]
    if len(ident) == 8 and int(ident, 16) & CAN_ERR_FLAG:
        return None  # an error frame (SocketCAN CAN_ERR_FLAG), not traffic
    try:
        return CanFrame(int(ident, 16), data, is_extended_id=len(ident) > 3,
                        timestamp=float(m["ts"]) if m["ts"] else 0.0, channel=m["ch"])
    except ValueError as exc:
        raise CanLogError(f"{source}:{lineno}: {exc}") from None


def read_lines(lines: Iterable[str], *, source: str = "<log>") -> Iterator[CanFrame]:
    """Frames of a candump-style log, in order; raises ``CanLogError`` at the first bad line."""
    for lineno, line in enumerate(lines, start=1):
        frame = parse_line(line, source=source, lineno=lineno)
        if frame is not None:
            yield frame


def format_line(frame: CanFrame, channel: str = "can0") -> str:
    """``candump -L`` form of a frame (python-can ``CanutilsLogWriter`` layout)."""
    ident = f"{frame.arbitration_id:08X}" if frame.is_extended_id else f"{frame.arbitration_id:03X}"
    return f"({frame.timestamp:.6f}) {frame.channel or channel} {ident}#{frame.data.hex().upper()}"
