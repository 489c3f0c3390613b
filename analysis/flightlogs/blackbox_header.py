"""The ``H name:value`` header of one blackbox log: settings and field definitions."""

from __future__ import annotations

import struct
from dataclasses import dataclass, field

from analysis.errors import LogError

__all__ = ["FrameDef", "Header", "parse_header"]

HEADER_MAX = 1 << 16  # a header is a few kB; more is no header


@dataclass
class FrameDef:
    """One frame type's fields: names, signedness, predictor and encoding per field."""

    names: list[str]
    signed: list[int]
    predictor: list[int]
    encoding: list[int]


@dataclass
class Header:
    values: dict[str, str]
    frames: dict[str, FrameDef] = field(default_factory=dict)
    length: int = 0  # bytes of header, the data starts here

    def int(self, name: str, default: int) -> int:
        try:
            return int(self.values[name].split(",")[0].strip(), 0)
        except (KeyError, ValueError):
            return default

    def ints(self, name: str) -> list[int]:
        try:
            return [int(v.strip(), 0) for v in self.values[name].split(",")]
        except (KeyError, ValueError):
            return []

    def float_bits(self, name: str, default: float) -> float:
        """A float32 written as its hex bits (``gyro_scale:0x3f800000``)."""
        raw = self.values.get(name, "").strip()
        try:
            return struct.unpack("<f", struct.pack("<I", int(raw, 16)))[0] if raw.startswith(
                "0x") else float(raw)
        except ValueError:
            return default

    @property
    def firmware(self) -> str:
        return self.values.get("Firmware revision") or self.values.get("Firmware type", "")


def _ints(text: str, what: str, where: str) -> list[int]:
    try:
        return [int(v) for v in text.split(",")] if text.strip() else []
    except ValueError:
        raise LogError(f"{where}: header {what}: not a list of integers "
                       f"({text[:60]!r})") from None


def parse_header(data: bytes, where: str) -> Header:
    """Parse the ``H`` lines at the start of ``data`` (one log, from its Product line)."""
    values: dict[str, str] = {}
    pos = 0
    while data.startswith(b"H ", pos) and pos < HEADER_MAX:
        end = data.find(b"\n", pos)
        if end < 0:
            raise LogError(f"{where}: the header ends inside a line (file cut in its header)")
        name, _, value = data[pos + 2:end].decode("latin-1").partition(":")
        values[name.strip()] = value.strip()
        pos = end + 1
    head = Header(values, length=pos)
    for letter in "IPSGH":
        names = values.get(f"Field {letter} name")
        base = "I" if letter == "P" else letter
        if letter == "P":
            names = values.get("Field I name")
        if not names or f"Field {letter} encoding" not in values:
            continue
        name_list = names.split(",")
        signed = _ints(values.get(f"Field {base} signed", ""), f"Field {base} signed", where)
        pred = _ints(values.get(f"Field {letter} predictor", ""), f"Field {letter} predictor",
                     where)
        enc = _ints(values[f"Field {letter} encoding"], f"Field {letter} encoding", where)
        if len(pred) != len(name_list) or len(enc) != len(name_list):
            raise LogError(f"{where}: header: {len(name_list)} {base} field names but "
                           f"{len(pred)} {letter} predictors and {len(enc)} encodings")
        signed = (signed + [0] * len(name_list))[:len(name_list)]
        head.frames[letter] = FrameDef(name_list, signed, pred, enc)
    return head
