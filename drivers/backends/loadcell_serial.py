"""A load-cell amplifier board that prints lines over serial (HX711 type), as a ``Sensor``.

The board's line format is whatever its firmware prints; a ``LineLayout`` (from the rig
file) maps fields to SI columns (protocols.md §8.2: there is no common standard). A
reader thread decodes lines as they come; text and header lines are skipped. Each line
is one row at the rig-clock time of reception (a board that prints its own time stamp
gives it as a column too, e.g. ``t_board_s``).
"""

from __future__ import annotations

from typing import Any

from drivers.backends.row_stream import SerialStreamSensor
from drivers.codecs.loadcell_lines import LineLayout, LoadcellLineDecoder
from drivers.contracts import ChannelInfo, Clock, DeviceInfo


class LineLoadCell(SerialStreamSensor):
    """Lines in, blocks out; ``read_block`` raises when no line came for ``stale_s``."""

    def __init__(self, port: Any, layout: LineLayout, *, clock: Clock | None = None,
                 stale_s: float = 0.5, url: str = "serial://loadcell") -> None:
        super().__init__(port, clock=clock, stale_s=stale_s, url=url)
        self.layout = layout
        self.names = tuple(f.name for f in layout.fields if f is not None)
        self.decoder = LoadcellLineDecoder(layout)
        self._start_reader(f"loadcell-{url}")

    def describe(self) -> DeviceInfo:
        return DeviceInfo(kind="load_cell", model="line-printing load-cell board", url=self.url,
                          channels=tuple(ChannelInfo(n, n.rsplit("_", 1)[-1], 0.0)
                                         for n in self.names),
                          extra={"separator": self.layout.separator})

    def _decode(self, data: bytes, now: float) -> list[tuple[float, ...]]:
        return [(now, *(ln.values[n] for n in self.names)) for ln in self.decoder.feed(data)]

    def _silence(self, silent_s: float) -> str:
        return (f"{self.url}: no data line for {silent_s:.3f} s "
                f"(skipped {self.decoder.stats.skipped_lines} text lines, "
                f"{self.decoder.stats.malformed} malformed)")
