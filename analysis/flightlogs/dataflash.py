"""ArduPilot DataFlash logs (``.bin``), read from the format's own FMT messages.

pymavlink's DFReader carries a GPL-3 header, so this reader is written from the format
(ArduPilot's ``LogStructure.h``): messages are ``A3 95 <type>`` + a body whose length
and layout the log's FMT messages (type 128) define. The file is read in windows
(``WINDOW`` bytes): a first pass collects the FMT messages (ArduPilot may write one just
before a type's first message), a second delimits every message with one regular
expression (lead bytes and type -> length) and gathers the wanted types' bodies into
numpy structured arrays, one column per FMT label, scaled by the format character
(``c``/``C``/``e``/``E`` x 0.01, ``L`` x 1e-7).

Kept (SI units): ``IMU`` instance 0 GyrX/Y/Z (rad/s, the time base, ``TimeUS``), ``RATE``
RDes/PDes/YDes (deg/s -> rad/s), ``RCOU`` C1.. (µs), ``ESC`` RPM per instance (rpm),
``BAT`` instance 0 Volt (V) and Curr (A).
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import BinaryIO

import numpy as np

from analysis.errors import LogError
from analysis.flightlogs.flight_log import AXES, MAX_ROWS, FlightLog, holder

__all__ = ["FORMAT_CHARS", "WINDOW", "read_dataflash"]

HEAD = b"\xa3\x95"
FMT_TYPE = 128
FMT_LEN = 89
WINDOW = 8 << 20
# format char -> (numpy dtype, scale applied to the stored value)
FORMAT_CHARS: dict[str, tuple[str | tuple[str, tuple[int]], float]] = {
    "a": ("<i2", 1.0), "b": ("i1", 1.0), "B": ("u1", 1.0), "h": ("<i2", 1.0),
    "H": ("<u2", 1.0), "i": ("<i4", 1.0), "I": ("<u4", 1.0), "f": ("<f4", 1.0),
    "d": ("<f8", 1.0), "n": ("S4", 1.0), "N": ("S16", 1.0), "Z": ("S64", 1.0),
    "c": ("<i2", 0.01), "C": ("<u2", 0.01), "e": ("<i4", 0.01), "E": ("<u4", 0.01),
    "L": ("<i4", 1e-7), "M": ("u1", 1.0), "q": ("<i8", 1.0), "Q": ("<u8", 1.0),
    "g": ("<f2", 1.0)}
_WANTED = ("IMU", "RATE", "RCOU", "ESC", "BAT")
_NEEDS = {"IMU": ("TimeUS", "GyrX", "GyrY", "GyrZ"), "RATE": ("TimeUS",), "RCOU": ("TimeUS",),
          "ESC": ("TimeUS", "RPM"), "BAT": ("TimeUS",)}  # columns a kept message must have
_FMT_HEAD = HEAD + bytes([FMT_TYPE])
_FMT_RX = re.compile(re.escape(_FMT_HEAD) + b".{%d}" % (FMT_LEN - 3), re.DOTALL)


@dataclass(frozen=True)
class MessageFormat:
    type: int
    length: int
    name: str
    format: str
    columns: list[str]

    def dtype(self) -> np.dtype:
        fields = []
        for ch, col in zip(self.format, self.columns, strict=True):
            dt = FORMAT_CHARS[ch][0]
            fields.append((col, ("<i2", (32,)) if ch == "a" else dt))
        return np.dtype(fields)


def _text(raw: bytes) -> str:
    return raw.split(b"\x00", 1)[0].decode("ascii", errors="replace")


def _parse_fmt(body: bytes) -> MessageFormat | None:
    """One FMT message body (86 bytes), or None if it is not a plausible one."""
    mtype, length = body[0], body[1]
    name, fmt, cols = _text(body[2:6]), _text(body[6:22]), _text(body[22:86]).split(",")
    if not re.fullmatch(r"[A-Za-z0-9_]{1,4}", name) or not fmt:
        return None
    if any(ch not in FORMAT_CHARS for ch in fmt) or len(cols) != len(fmt):
        return None
    try:
        mf = MessageFormat(mtype, length, name, fmt, cols)
        size = mf.dtype().itemsize
    except (ValueError, TypeError):  # a repeated column name, ...
        return None
    return mf if size + 3 == length else None


def _windows(fh: BinaryIO, size: int, overlap: int):
    """(file offset of the window, bytes) with ``overlap`` bytes repeated between windows."""
    offset = 0
    while offset < size:
        fh.seek(offset)
        chunk = fh.read(WINDOW + overlap)
        yield offset, chunk
        if offset + len(chunk) >= size:
            return
        offset += WINDOW


def _formats(fh: BinaryIO, size: int, where: str) -> dict[int, MessageFormat]:
    found: dict[int, MessageFormat] = {}
    for _, chunk in _windows(fh, size, FMT_LEN):
        # memchr-fast: the regex engine walks no empty window. The lead byte alone first:
        # CPython's search for the three bytes skips a zero-filled window byte by byte
        # (0x80's low six bits are a zero's: its skip filter lets every zero through)
        if HEAD[:1] not in chunk or _FMT_HEAD not in chunk:
            continue
        for m in _FMT_RX.finditer(chunk):
            mf = _parse_fmt(m.group()[3:])
            if mf is not None and mf.type not in found:
                found[mf.type] = mf
    if FMT_TYPE not in found:
        raise LogError(f"{where}: no DataFlash FMT message (not an ArduPilot .bin log?)")
    return found


def _message_regex(formats: dict[int, MessageFormat]) -> re.Pattern[bytes]:
    by_len: dict[int, list[int]] = {}
    for mf in formats.values():
        by_len.setdefault(mf.length, []).append(mf.type)
    alts = b"|".join(b"[" + b"".join(re.escape(bytes([t])) for t in types) + b"]"
                     + (b".{%d}" % (length - 3)) for length, types in sorted(by_len.items()))
    return re.compile(re.escape(HEAD) + b"(?:" + alts + b")|[^\xa3]+|.", re.DOTALL)


def _collect(fh: BinaryIO, size: int, formats: dict[int, MessageFormat], max_rows: int
             ) -> tuple[dict[str, np.ndarray], int, int, bool]:
    """The wanted messages as structured arrays; (arrays, garbage bytes, messages, cut)."""
    rx = _message_regex(formats)
    wanted = {mf.type: mf for mf in formats.values() if mf.name in _WANTED}
    parts: dict[int, list[np.ndarray]] = {t: [] for t in wanted}
    imu = [t for t, mf in wanted.items() if mf.name == "IMU"]
    garbage = messages = 0
    offset, carry, cut = 0, b"", False
    while offset < size:
        fh.seek(offset)
        fresh = fh.read(min(WINDOW, size - offset))
        offset += len(fresh)
        chunk = carry + fresh
        last = offset >= size
        if HEAD[:1] not in chunk:  # no message starts here (a zero-filled tail): skip it
            garbage, carry = garbage + len(chunk), b""
            continue
        items = rx.findall(chunk)
        lengths = np.fromiter(map(len, items), np.int64, len(items))
        starts = np.cumsum(lengths) - lengths
        keep = len(items)
        if not last:  # the last items may be cut by the window: read them again
            whole = np.flatnonzero(starts + 512 < len(chunk))
            keep = int(whole[-1]) + 1 if len(whole) else len(items)
        buf = np.frombuffer(chunk + bytes(3), np.uint8)
        st, ln = starts[:keep], lengths[:keep]
        is_msg = (buf[st] == 0xA3) & (buf[st + 1] == 0x95) & (ln > 2)
        garbage += int(ln[~is_msg].sum())
        messages += int(is_msg.sum())
        types = np.where(is_msg, buf[st + 2], -1)
        for t, mf in wanted.items():
            sel = st[types == t]
            if len(sel):
                raw = buf[sel[:, None] + np.arange(3, mf.length)]
                parts[t].append(raw.copy().view(mf.dtype()).ravel())
        carry = chunk[int(starts[keep]):] if keep < len(items) else b""
        if imu and sum(len(p) for p in parts[imu[0]]) > max_rows:
            cut = True
            break
    arrays = {wanted[t].name: np.concatenate(p) for t, p in parts.items() if p}
    return arrays, garbage, messages, cut


def _col(arr: np.ndarray, mf_format: str, columns: list[str], name: str) -> np.ndarray:
    """A numeric column scaled by its format character; NaN where the FMT (another
    layout, or damaged) made it text or an array."""
    v = arr[name]
    if v.dtype.kind not in "iuf" or v.ndim != 1:
        return np.full(len(arr), np.nan)
    scale = FORMAT_CHARS[mf_format[columns.index(name)]][1]
    with np.errstate(invalid="ignore"):  # a damaged float32 may be a signalling NaN
        return v.astype(float) * scale


def read_dataflash(path: str | Path, *, max_rows: int | None = None) -> FlightLog:
    path = Path(path)
    where = str(path)
    max_rows = MAX_ROWS if max_rows is None else max_rows
    try:
        with open(path, "rb") as fh:
            size = fh.seek(0, 2)
            formats = _formats(fh, size, where)
            arrays, garbage, messages, cut = _collect(fh, size, formats, max_rows)
    except OSError as exc:
        raise LogError(f"{path}: cannot read ({exc.strerror or exc})") from None
    by_name = {mf.name: mf for mf in formats.values()}
    notes: list[str] = []
    for name in list(arrays):
        cols = by_name[name].columns
        missing = [c for c in _NEEDS[name] if c not in cols
                   or arrays[name][c].dtype.kind not in "iuf" or arrays[name][c].ndim != 1]
        if missing:  # another layout, or a damaged FMT
            del arrays[name]
            if name == "IMU":
                raise LogError(f"{where}: the IMU message has no numeric {', '.join(missing)} "
                               f"(its FMT columns: {','.join(by_name[name].columns)[:80]})")
            notes.append(f"left out {name}: its FMT has no numeric {', '.join(missing)}")
    if "IMU" not in arrays:
        raise LogError(f"{where}: no IMU message ({messages} messages of "
                       f"{len(formats)} types; the gyro is the time base)")
    imu, f = arrays["IMU"], by_name["IMU"]
    if "I" in f.columns:
        imu = imu[imu["I"] == 0]
    imu = imu[:max_rows]
    if len(imu) == 0:
        raise LogError(f"{where}: no IMU message of instance 0 (the gyro is the time base)")
    t_us = imu["TimeUS"].astype(np.int64)
    order = np.argsort(t_us, kind="stable")
    imu, t_us = imu[order], t_us[order]
    ok = np.concatenate([[True], np.diff(t_us) > 0])
    imu, t_us = imu[ok], t_us[ok]
    t0 = int(t_us[0])
    base = (t_us - t0) * 1e-6
    if cut:
        notes.append(f"kept the first {max_rows} IMU samples (--max-rows); the rest of the "
                     "log was not read")
    if garbage:
        notes.append(f"skipped {garbage} bytes that are no message (a cut or damaged log?)")
    log = FlightLog({}, {"format": "dataflash", "firmware": "ArduPilot",
                         "messages": messages, "types": len(formats), "notes": notes,
                         "time_base": f"IMU[0].TimeUS, 0 = {t0} µs after boot",
                         "hold": "slower messages held at their last value "
                                 "(NaN before their first)"})
    log.add("t_s", base, "s", "IMU.TimeUS")
    for axis, c in zip(AXES, ("GyrX", "GyrY", "GyrZ"), strict=True):
        log.add(f"gyro_{axis}_rad_s", _col(imu, f.format, f.columns, c), "rad/s", f"IMU.{c}")

    def held(arr: np.ndarray) -> Callable[[np.ndarray], np.ndarray]:
        """Hold any column of these messages onto the IMU times."""
        return holder(base, (arr["TimeUS"].astype(np.int64) - t0) * 1e-6)

    if "RATE" in arrays:
        r, f = arrays["RATE"], by_name["RATE"]
        h = held(r)
        for axis, c in zip(AXES, ("RDes", "PDes", "YDes"), strict=True):
            if c in f.columns:
                v = _col(r, f.format, f.columns, c) * math.pi / 180
                log.add(f"rate_sp_{axis}_rad_s", h(v), "rad/s", f"RATE.{c} (deg/s)")
    if "RCOU" in arrays:
        r, f = arrays["RCOU"], by_name["RCOU"]
        h = held(r)
        for c in f.columns:
            if re.fullmatch(r"C\d+", c) and np.any(r[c] != 0):
                log.add(f"output{c[1:]}_us", h(_col(r, f.format, f.columns, c)),
                        "µs", f"RCOU.{c}")
    if "ESC" in arrays:
        r, f = arrays["ESC"], by_name["ESC"]
        inst = r["Instance"] if "Instance" in f.columns else np.zeros(len(r), int)
        for k in sorted(set(inst.tolist()))[:12]:
            e = r[inst == k]
            log.add(f"motor{k + 1}_rpm", held(e)(_col(e, f.format, f.columns, "RPM")),
                    "rpm", f"ESC[{k}].RPM")
    if "BAT" in arrays:
        r, f = arrays["BAT"], by_name["BAT"]
        if "Instance" in f.columns:
            r = r[r["Instance"] == 0]
        h = held(r)
        for c, name in (("Volt", "voltage_v"), ("Curr", "current_a")):
            if c in f.columns and len(r):
                log.add(name, h(_col(r, f.format, f.columns, c)),
                        "V" if c == "Volt" else "A", f"BAT.{c}")
    return log
