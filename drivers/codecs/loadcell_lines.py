"""Line-oriented load-cell boards (HX711 amplifier + microcontroller printing text lines).

There is no common standard (protocols.md §8.2): each firmware prints its own CSV-like
line, usually after some human text and a header. A ``LineLayout`` says which field is
which and how to scale it to SI; ``LoadcellLineDecoder`` turns the byte stream into
``LoadcellLine``s (``{column: value}``) and counts what it skips: text and header lines
(``skipped_lines``), lines of the wrong shape (``malformed``), over-long lines and stray
bytes (``garbage_bytes``), an unterminated last line (``truncated``). A line that lost its
terminator glues onto the next one; the pair is usually counted as one malformed line, but
can parse as one wrong line (a line protocol without checksum cannot tell).

Column names carry their unit (``thrust_n``, ``t_s``, ``voltage_v``) as in the run
records; the datasheet/firmware unit is converted here, by the layout, and nowhere else.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

from drivers.codecs.stream import DecoderStats, Located
from drivers.errors import DeviceError

GRAM_FORCE_N = 9.80665e-3  # 1 gram-force in N (standard gravity 9.80665 m/s², protocols.md §2.2)
DEFAULT_MAX_LINE = 256  # bytes; longer lines are noise


class LayoutError(DeviceError):
    """A line layout (from a rig file) is invalid; names the field and what was expected."""


@dataclass(frozen=True)
class Field:
    """One field of the line: output column name, ``value = raw * scale + offset``."""

    name: str
    scale: float = 1.0
    offset: float = 0.0


@dataclass(frozen=True)
class LineLayout:
    """How a board's lines look. ``fields`` in order; ``None`` entries are ignored fields."""

    fields: tuple[Field | None, ...]
    separator: str = ","

    def __post_init__(self) -> None:
        names = [f.name for f in self.fields if f is not None]
        if not names:
            raise LayoutError("line layout: at least one named field is needed")
        if len(set(names)) != len(names):
            raise LayoutError(f"line layout: duplicate field names in {names}")
        if not self.separator or "\n" in self.separator:
            raise LayoutError(f"line layout: separator {self.separator!r} is not usable")

    @classmethod
    def from_config(cls, config: Mapping[str, object], source: str = "<layout>") -> LineLayout:
        """Layout from a rig-file table: ``separator = ","`` and ``fields = [...]`` where
        each entry is a name, ``""`` (ignored field) or ``{name, scale, offset}``."""
        raw = config.get("fields")
        if not isinstance(raw, Sequence) or isinstance(raw, str) or not raw:
            raise LayoutError(f"{source}: 'fields' must be a non-empty list")
        fields: list[Field | None] = []
        for k, entry in enumerate(raw):
            where = f"{source}: fields[{k}]"
            if isinstance(entry, str):
                fields.append(Field(entry) if entry else None)
                continue
            if not isinstance(entry, Mapping) or not isinstance(entry.get("name"), str):
                raise LayoutError(f"{where}: expected a name or a table with 'name'")
            try:
                scale = float(entry.get("scale", 1.0))
                offset = float(entry.get("offset", 0.0))
            except (TypeError, ValueError):
                raise LayoutError(f"{where}: 'scale' and 'offset' must be numbers") from None
            if not (math.isfinite(scale) and math.isfinite(offset)) or scale == 0:
                raise LayoutError(f"{where}: scale must be finite and non-zero, offset finite")
            fields.append(Field(str(entry["name"]), scale, offset))
        sep = config.get("separator", ",")
        if not isinstance(sep, str):
            raise LayoutError(f"{source}: 'separator' must be a string")
        return cls(tuple(fields), sep)

    def parse(self, line: str) -> dict[str, float] | None:
        """Values of one line, or ``None`` when it does not fit the layout."""
        parts = line.split(self.separator) if self.separator.strip() else line.split()
        if len(parts) != len(self.fields):
            return None
        out: dict[str, float] = {}
        for f, text in zip(self.fields, parts, strict=True):
            if f is None:
                continue
            try:
                v = float(text)
            except ValueError:
                return None
            if not math.isfinite(v):
                return None
            out[f.name] = v * f.scale + f.offset
        return out

    def format(self, values: Mapping[str, float]) -> str:
        """The board's line for SI values (inverse of ``parse``; for simulators)."""
        return self.separator.join(
            "0" if f is None else format((values[f.name] - f.offset) / f.scale, ".10g")
            for f in self.fields)


# protocols.md §8.2 (VirtualEnder/TestStandv2 main test): header
# "Thrust(g),mSteps,Throttle(uS),Time(uS),mPRMs,Volts,Amps", CRLF lines at 921600 baud.
TESTSTAND_V2 = LineLayout((
    Field("thrust_n", GRAM_FORCE_N),
    Field("steps"),
    Field("throttle_us"),
    Field("t_s", 1e-6),
    Field("rpm"),
    Field("voltage_v"),
    Field("current_a"),
))
TESTSTAND_V2_BAUD = 921_600  # §8.2 UARTBAUD

# The simplest HX711 board: "<raw counts>" per line; calibration happens in the driver
# (§8.1: units = (raw - OFFSET) / SCALE).
HX711_RAW = LineLayout((Field("raw"),))


@dataclass(frozen=True)
class LoadcellLine:
    """One data line in SI columns."""

    values: dict[str, float] = field(default_factory=dict)


@dataclass
class LineStats(DecoderStats):
    """``DecoderStats`` plus the count of text/header lines skipped on purpose."""

    skipped_lines: int = 0


class LoadcellLineDecoder:
    """Bytes -> ``LoadcellLine``s for a ``LineLayout``; never raises or blocks.

    A line that does not fit is *skipped* when it holds a letter (human text, CSV
    header) and *malformed* otherwise (numbers of the wrong count: a damaged line).
    """

    def __init__(self, layout: LineLayout, max_line: int = DEFAULT_MAX_LINE) -> None:
        self.layout = layout
        self.max_line = max_line
        self.stats = LineStats()
        self._cur = bytearray()
        self._start = 0
        self._pos = 0
        self._overflow = False

    @property
    def buffered(self) -> int:
        return len(self._cur)

    def feed(self, data: bytes | bytearray) -> list[LoadcellLine]:
        return [loc.message for loc in self.feed_located(data)]

    def feed_located(self, data: bytes | bytearray) -> list[Located[LoadcellLine]]:
        st = self.stats
        st.bytes_in += len(data)
        out: list[Located[LoadcellLine]] = []
        base = self._pos
        self._pos += len(data)
        data = bytes(data)
        i = 0
        while i < len(data):
            nl = data.find(b"\n", i)
            chunk = data[i:] if nl < 0 else data[i : nl + 1]
            if self._overflow:
                st.garbage_bytes += len(chunk)
                self._overflow = nl < 0
                i += len(chunk)
                continue
            if not self._cur:
                self._start = base + i
            self._cur += chunk
            i += len(chunk)
            if len(self._cur) > self.max_line:
                st.garbage_bytes += len(self._cur)
                st.malformed += 1
                self._cur.clear()
                self._overflow = nl < 0
                continue
            if nl >= 0:
                msg = self._line(bytes(self._cur))
                if msg is not None:
                    out.append(Located(self._start, msg, len(self._cur)))
                self._cur.clear()
        return out

    def flush(self) -> list[LoadcellLine]:
        return [loc.message for loc in self.flush_located()]

    def flush_located(self) -> list[Located[LoadcellLine]]:
        """End of stream: an unterminated last line counts as truncated."""
        if self._cur:
            self.stats.truncated += 1
            self.stats.garbage_bytes += len(self._cur)
            self._cur.clear()
        return []

    def _line(self, raw: bytes) -> LoadcellLine | None:
        st = self.stats
        text = raw.decode("ascii", errors="replace").strip()
        values = self.layout.parse(text) if text else None
        if values is not None:
            st.messages += 1
            st.frame_bytes += len(raw)
            return LoadcellLine(values)
        st.garbage_bytes += len(raw)
        if any(c.isalpha() for c in text.replace("e", "").replace("E", "")) or not text:
            st.skipped_lines += 1 if text else 0
        else:
            st.malformed += 1
        return None
