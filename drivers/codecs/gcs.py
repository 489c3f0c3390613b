"""PI GCS text protocol (hexapod controllers such as the C-887) over TCP port 50000.

Commands are ASCII (cp1252) lines ending with LF; a few single-character commands go
without LF. A reply is complete at an LF *not* preceded by a space; every non-final line
of a multi-line reply ends with space + LF. Facts: protocols.md §6.1-§6.3 (PIPython
``gcsmessages.py``, ``pisocket.py``, ``gcs2commands.py``, ``gcserror.py``; ESRF bliss).

This module builds command lines (floats formatted like pipython, ``'.12g'``), splits a
byte stream into replies (``GcsReplyDecoder``) or commands (``GcsCommandDecoder``), and
parses replies: ``AXIS=value`` lines, error codes, ``*IDN?`` and ``DRR?`` data arrays.
Hexapod axes are X, Y, Z in mm and U, V, W in degrees (§6.2); the pivot-point axis
letters R, S, T are unverified in protocols.md, so ``spi`` takes whatever names the
controller reports.
"""

from __future__ import annotations

import re
from collections.abc import Iterable, Mapping
from dataclasses import dataclass

import numpy as np

from drivers.codecs.stream import DecoderStats, Located
from drivers.errors import DeviceError

PORT = 50000  # §6.1
ENCODING = "cp1252"  # §6.1
SERVO_CYCLE_S_C887 = 100e-6  # §6.3 pipython SERVOTIMES['C-887']
HEXAPOD_AXES = ("X", "Y", "Z", "U", "V", "W")  # §6.2 (bliss CHANNELS)

# §6.1 single-character commands (sent without LF)
POSITION_NOW = b"\x03"  # #3
IS_MOVING = b"\x05"  # #5 -> hex bit mask, one bit per axis
POSITION_CHANGED = b"\x06"  # #6
READY = b"\x07"  # #7 -> chr(177) ready / chr(176) busy
MACRO_RUNNING = b"\x08"  # #8
WAVE_RUNNING = b"\x09"  # #9 -> hex mask
STOP_ALL = b"\x18"  # #24
SINGLE_CHAR_COMMANDS = {0x03: "#3", 0x05: "#5", 0x06: "#6", 0x07: "#7", 0x08: "#8", 0x09: "#9",
                        0x18: "#24"}
READY_CHAR, BUSY_CHAR = chr(177), chr(176)

# §6.3 error codes (gcserror.py, subset)
ERRORS: dict[int, str] = {
    0: "no error", 1: "parameter syntax error", 2: "unknown command", 3: "command too long",
    5: "move without reference or with servo off", 7: "position out of limits",
    8: "velocity out of limits", 9: "setting pivot point not possible", 10: "stopped by command",
    15: "invalid axis", 17: "parameter out of range", 26: "missing parameter",
}
STOPPED_BY_COMMAND = 10  # §6.3: ERR? after STP/HLT/#24

# §6.3 DRC record options
RECORD_COMMANDED_POSITION = 1
RECORD_ACTUAL_POSITION = 2
RECORD_POSITION_ERROR = 3
RECORD_TIMESTAMP = 8


class GcsReplyError(DeviceError):
    """A reply does not have the shape the command promises."""


# ---------------------------------------------------------------------------- commands


def _fmt(v: object) -> str:
    if isinstance(v, bool):
        return "1" if v else "0"
    if isinstance(v, float):
        return format(v, ".12g")  # §6.1 pipython float format
    return str(v)


def command(name: str, *args: object) -> bytes:
    """One GCS command line, e.g. ``command("WGO", 1, 1)`` -> ``b"WGO 1 1\\n"``."""
    text = " ".join([name, *(_fmt(a) for a in args)])
    if "\n" in text:
        raise ValueError("a GCS command must not contain a line feed")
    return (text + "\n").encode(ENCODING)


def _axes_values(name: str, values: Mapping[str, float]) -> bytes:
    if not values:
        raise ValueError(f"{name} needs at least one axis")
    return command(name, *(x for kv in values.items() for x in (kv[0], float(kv[1]))))


def idn() -> bytes:
    return command("*IDN?")


def csv_query() -> bytes:
    """GCS syntax version, asked first by pipython (§6.2)."""
    return command("CSV?")


def sai_query() -> bytes:
    return command("SAI?")


def err_query() -> bytes:
    return command("ERR?")


def mov(target: Mapping[str, float]) -> bytes:
    """Absolute move; all axes start together (§6.3), e.g. ``MOV X 1 Y 0.5``."""
    return _axes_values("MOV", target)


def mvr(delta: Mapping[str, float]) -> bytes:
    return _axes_values("MVR", delta)


def pos_query(axes: Iterable[str] = ()) -> bytes:
    return command("POS?", *axes)


def ont_query(axes: Iterable[str] = ()) -> bytes:
    return command("ONT?", *axes)


def spi(pivot: Mapping[str, float]) -> bytes:
    """Set the pivot point (rotation centre), §6.3; axis names as the controller uses."""
    return _axes_values("SPI", pivot)


def spi_query() -> bytes:
    return command("SPI?")


def vls(velocity: float) -> bytes:
    """Hexapod platform velocity (§6.3)."""
    return command("VLS", float(velocity))


def svo(axes: Mapping[str, bool]) -> bytes:
    return command("SVO", *(x for kv in axes.items() for x in (kv[0], bool(kv[1]))))


def frf(axes: Iterable[str] = ("X",)) -> bytes:
    """Reference move (C-887: ``FRF X``, §6.3)."""
    return command("FRF", *axes)


def stp() -> bytes:
    return command("STP")


def hlt(axes: Iterable[str] = ()) -> bytes:
    return command("HLT", *axes)


def wav_sin_p(table: int, seg_length: int, amplitude: float, offset: float, num_points: int,
              first_point: int, center: int, append: str = "X") -> bytes:
    """Wave table with a sine (§6.3 ``WAV <table> <X|&|+> SIN_P <seglength> <amplitude>
    <offset> <numpoints> <firstpoint> <center>``)."""
    if append not in ("X", "&", "+"):
        raise ValueError(f"WAV append mode must be X, & or +, got {append!r}")
    return command("WAV", table, append, "SIN_P", seg_length, float(amplitude), float(offset),
                   num_points, first_point, center)


def wav(table: int, append: str, curve: str, *params: object) -> bytes:
    """Any wave table shape (LIN, RAMP, PNT, SWEEP, POL, TAN, NOISE, §6.3)."""
    return command("WAV", table, append, curve, *params)


def wsl(generator: int, table: int) -> bytes:
    """Connect a wave generator to a wave table."""
    return command("WSL", generator, table)


def wgc(generator: int, cycles: int) -> bytes:
    return command("WGC", generator, cycles)


def wtr(generator: int, table_rate: int, interpolation: int = 0) -> bytes:
    """Table rate in servo cycles per point (§6.3)."""
    return command("WTR", generator, table_rate, interpolation)


def wgo(generator: int, mode: int) -> bytes:
    """Start (mode 1) or stop (mode 0) a wave generator."""
    return command("WGO", generator, mode)


def drc(table: int, source: str, option: int) -> bytes:
    """Data recorder table configuration: record ``option`` of ``source`` (§6.3)."""
    return command("DRC", table, source, option)


def rtr(servo_cycles: int) -> bytes:
    """Record table rate, in servo cycles per point."""
    return command("RTR", servo_cycles)


def drr_query(offset: int, count: int, tables: Iterable[int]) -> bytes:
    return command("DRR?", offset, count, *tables)


# ---------------------------------------------------------------------------- replies


@dataclass(frozen=True)
class GcsReply:
    """One complete reply, split into lines (terminators removed)."""

    lines: tuple[str, ...]


@dataclass(frozen=True)
class GcsCommand:
    """One command seen on the host side: name and arguments as text."""

    name: str
    args: tuple[str, ...] = ()


@dataclass(frozen=True)
class Identification:
    """``*IDN?`` reply fields (§6.2): vendor, model, serial, firmware."""

    vendor: str
    model: str
    serial: str
    firmware: str


@dataclass(frozen=True)
class DataArray:
    """A GCS data array (``DRR?`` reply): ``# KEY = value`` header, then columns."""

    header: dict[str, str]
    data: np.ndarray  # (rows, columns)


def encode_reply(lines: Iterable[str]) -> bytes:
    """Controller-side bytes of a reply (§6.1 termination rule)."""
    lines = list(lines)
    if not lines:
        raise ValueError("a reply has at least one line")
    if lines[-1].endswith(" "):
        raise ValueError("the final reply line must not end with a space")
    return ("".join(f"{ln} \n" for ln in lines[:-1]) + lines[-1] + "\n").encode(ENCODING)


def encode_axis_values(values: Mapping[str, float]) -> bytes:
    """``X=1 \\nY=0.5\\n`` reply of a query such as ``POS?``."""
    return encode_reply(f"{k}={_fmt(float(v))}" for k, v in values.items())


def parse_axis_values(reply: GcsReply) -> dict[str, float]:
    """``AXIS=value`` lines -> {axis: value}."""
    out: dict[str, float] = {}
    for ln in reply.lines:
        key, sep, val = ln.partition("=")
        try:
            if not sep or not key.strip():
                raise ValueError
            out[key.strip()] = float(val)
        except ValueError:
            raise GcsReplyError(f"GCS reply line {ln!r}: expected AXIS=number") from None
    return out


def parse_error_code(reply: GcsReply) -> int:
    """``ERR?`` reply -> integer code (0 = no error)."""
    try:
        (line,) = reply.lines
        return int(line.strip())
    except ValueError:
        raise GcsReplyError(f"GCS ERR? reply {reply.lines!r}: expected one integer") from None


def parse_idn(reply: GcsReply) -> Identification:
    parts = [p.strip() for p in " ".join(reply.lines).split(",")]
    if len(parts) != 4:
        raise GcsReplyError(f"GCS *IDN? reply {reply.lines!r}: expected "
                            "vendor,model,serial,firmware")
    return Identification(*parts)


_HEADER = re.compile(r"^#\s*(?P<key>[^=]+?)\s*=\s*(?P<val>.*?)\s*$")


def parse_data_array(reply: GcsReply) -> DataArray:
    """``DRR?`` reply -> header dict and an array of the numeric rows (§6.3)."""
    header: dict[str, str] = {}
    rows: list[list[float]] = []
    in_header = True
    for ln in reply.lines:
        text = ln.strip()
        if in_header:
            if text.startswith("#"):
                if text.lstrip("# ").startswith("END_HEADER"):
                    in_header = False
                    continue
                m = _HEADER.match(text)
                if m:
                    header[m["key"]] = m["val"]
                continue
            in_header = False
        if not text:
            continue
        try:
            rows.append([float(x) for x in text.split()])
        except ValueError:
            raise GcsReplyError(f"GCS data line {ln!r}: expected numbers") from None
    if rows and len({len(r) for r in rows}) != 1:
        raise GcsReplyError("GCS data array: rows of different lengths")
    return DataArray(header, np.array(rows, dtype=float).reshape(len(rows), -1))


def reply_kind(reply: GcsReply) -> str:
    """A guess at what a reply holds, for ``rotorbench decode``: ``axis_values``,
    ``data_array``, ``integer``, ``ready``/``busy`` or ``text``."""
    if reply.lines[0].lstrip().startswith("#"):
        return "data_array"
    try:
        parse_axis_values(reply)
        return "axis_values"
    except GcsReplyError:
        pass
    if len(reply.lines) == 1:
        t = reply.lines[0].strip()
        if t == READY_CHAR:
            return "ready"
        if t == BUSY_CHAR:
            return "busy"
        if re.fullmatch(r"-?\d+", t):
            return "integer"
    return "text"


# ---------------------------------------------------------------------------- stream decoders

# bytes undefined in cp1252 and control characters other than TAB, CR, LF: never in GCS text
_BAD = frozenset([*range(0x00, 0x09), 0x0B, 0x0C, *range(0x0E, 0x20), 0x7F,
                  0x81, 0x8D, 0x8F, 0x90, 0x9D])
_BAD_BYTES = bytes(sorted(_BAD))
DEFAULT_MAX_REPLY = 1 << 20  # bytes; DRR? replies can be long


_DROP = object()  # returned by ``_step``: the bytes so far are garbage


class _TextDecoder:
    """Shared line splitting with counters (``DecoderStats``); never raises or blocks."""

    keep: frozenset[int] = frozenset()
    keep_inside = False  # a byte never in GCS text inside a message: keep it (to reject)

    def __init__(self, max_bytes: int = DEFAULT_MAX_REPLY) -> None:
        self.stats = DecoderStats()
        self.max_bytes = max_bytes
        self._cur = bytearray()
        self._cur_start = 0
        self._pos = 0  # absolute offset of the next byte fed
        self._overflow = False

    def feed(self, data: bytes | bytearray) -> list:
        return [loc.message for loc in self.feed_located(data)]

    def flush(self) -> list:
        return [loc.message for loc in self.flush_located()]

    def flush_located(self) -> list[Located]:
        """End of stream: an unterminated reply or command counts as truncated."""
        if self._cur:
            self.stats.truncated += 1
            self.stats.garbage_bytes += len(self._cur)
            self._cur.clear()
        return []

    @property
    def buffered(self) -> int:
        return len(self._cur)

    def feed_located(self, data: bytes | bytearray) -> list[Located]:
        out: list[Located] = []
        st = self.stats
        st.bytes_in += len(data)
        for b in bytes(data):
            pos = self._pos
            self._pos += 1
            if self._overflow:  # skipping the rest of an over-long line
                st.garbage_bytes += 1
                self._overflow = b != 0x0A
                continue
            if b in _BAD and b not in self.keep and not (self.keep_inside and self._cur):
                st.garbage_bytes += 1
                continue
            if not self._cur:
                self._cur_start = pos
            self._cur.append(b)
            self._settle(self._step(b), b, out)
        return out

    def _settle(self, msg: object | None, b: int, out: list[Located]) -> None:
        """After byte ``b`` joined the line: ``_step``'s verdict ``msg`` ends it as a
        message or as garbage, or the line has grown too long."""
        st = self.stats
        if msg is _DROP:
            st.garbage_bytes += len(self._cur)
            self._cur.clear()
        elif msg is not None:
            st.messages += 1
            st.frame_bytes += len(self._cur)
            out.append(Located(self._cur_start, msg, len(self._cur)))
            self._cur.clear()
        elif len(self._cur) > self.max_bytes:
            st.malformed += 1
            st.garbage_bytes += len(self._cur)
            self._cur.clear()
            self._overflow = b != 0x0A

    def _step(self, b: int) -> object | None:
        raise NotImplementedError


# what a controller's reply is made of (§6.1): printable ASCII lines (TAB, CRLF allowed),
# or the single ready/busy character of ``#7``
_REPLY_TEXT = re.compile(r"[\x20-\x7e\t\r\n]*")


def is_reply_text(text: str) -> bool:
    """True if ``text`` (a terminated reply, cp1252) can be a GCS controller's reply."""
    return text.strip() in (READY_CHAR, BUSY_CHAR) or _REPLY_TEXT.fullmatch(text) is not None


class GcsReplyDecoder(_TextDecoder):
    """Splits the controller's byte stream into ``GcsReply``s (§6.1 termination rule).

    ``strict`` (``rotorbench decode``): only what can be a controller's reply
    (:func:`is_reply_text`) is a message; a line with other bytes, control bytes inside it
    included, counts as garbage. Random bytes then decode to (almost) nothing instead of a
    "reply" per line feed. The driver keeps the lenient default: a reply it cannot parse
    is reported by the parser, not silently dropped.
    """

    def __init__(self, max_bytes: int = DEFAULT_MAX_REPLY, strict: bool = False) -> None:
        super().__init__(max_bytes)
        self.strict = self.keep_inside = strict

    def feed_located(self, data: bytes | bytearray) -> list[Located]:
        """Reply by reply where that is the same as byte by byte: a chunk of GCS text
        without a byte to drop, read leniently, no reply growing past ``max_bytes``. The data
        recorder's replies (``DRR?``) are such text, about 12 MB in a quick calibration
        through the wire: 15x faster so (benchmarks/gcs_decode.py). Anything else goes
        the byte-wise way."""
        data = bytes(data)
        if (self.strict or self._overflow
                or len(data.translate(None, _BAD_BYTES)) != len(data)):
            return super().feed_located(data)
        # where a reply may end: a line feed not after a space (" \n" continues it, §6.1);
        # a line feed first in the chunk follows the buffer's last byte: ``_step`` decides
        ends = data.replace(b" \n", b"  ")
        out: list[Located] = []
        start, n = 0, len(data)
        while start < n:
            lf = ends.find(b"\n", start)
            end = n if lf < 0 else lf + 1
            if len(self._cur) + (end - start) > self.max_bytes:  # an over-long line
                return out + super().feed_located(data[start:])
            if not self._cur:
                self._cur_start = self._pos
            self._cur += data[start:end]
            self._pos += end - start
            self.stats.bytes_in += end - start
            if lf >= 0:
                self._settle(self._step(0x0A), 0x0A, out)
            start = end
        return out

    def _step(self, b: int) -> object | None:
        cur = self._cur
        if b != 0x0A or (len(cur) >= 2 and cur[-2] == 0x20):
            return None
        text = cur.decode(ENCODING, errors="replace")
        if not text.strip():  # an empty line is not a reply
            return _DROP
        if self.strict and not is_reply_text(text):
            return _DROP
        lines = text[:-1].split("\n")
        return GcsReply(tuple((ln[:-1] if ln.endswith(" ") else ln).rstrip("\r") for ln in lines))


_LINE_BAD = frozenset(SINGLE_CHAR_COMMANDS) - {0x09}  # TAB inside a line is whitespace


class GcsCommandDecoder(_TextDecoder):
    """Splits the host's byte stream into ``GcsCommand``s (lines and single-char commands)."""

    keep = frozenset(SINGLE_CHAR_COMMANDS)

    def _step(self, b: int) -> object | None:
        if b in SINGLE_CHAR_COMMANDS and len(self._cur) == 1:
            return GcsCommand(SINGLE_CHAR_COMMANDS[b])
        if b in _LINE_BAD:  # a control byte inside a line is not a command: drop it
            self._cur.pop()
            self.stats.garbage_bytes += 1
            return None
        if b != 0x0A:
            return None
        parts = self._cur.decode(ENCODING).split()
        if not parts:
            return _DROP
        return GcsCommand(parts[0], tuple(parts[1:]))
