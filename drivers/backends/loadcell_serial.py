"""A load-cell amplifier board that prints lines over serial (HX711 type), as a ``Sensor``.

The board's line format is whatever its firmware prints; a ``LineLayout`` (from the rig
file) maps fields to SI columns (protocols.md §8.2: there is no common standard). A
reader thread decodes lines as they come; text and header lines are skipped. Each line
is one row at the rig-clock time of reception (a board that prints its own time stamp
gives it as a column too, e.g. ``t_board_s``).
"""

from __future__ import annotations

import threading
from typing import Any

import numpy as np

from drivers.backends.serial_link import read_some
from drivers.codecs.loadcell_lines import LineLayout, LoadcellLineDecoder
from drivers.contracts import Block, ChannelInfo, Clock, DeviceInfo, MonotonicClock
from drivers.errors import DeviceError


class LineLoadCell:
    """Lines in, blocks out; ``read_block`` raises when no line came for ``stale_s``."""

    def __init__(self, port: Any, layout: LineLayout, *, clock: Clock | None = None,
                 stale_s: float = 0.5, url: str = "serial://loadcell") -> None:
        self.port = port
        self.layout = layout
        self.clock = clock or MonotonicClock()
        self.stale_s = stale_s
        self.url = url
        self.names = tuple(f.name for f in layout.fields if f is not None)
        self.decoder = LoadcellLineDecoder(layout)
        self._rows: list[tuple[float, ...]] = []
        self._error: DeviceError | None = None
        self._last = self.clock.now()
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._read, name=f"loadcell-{url}", daemon=True)
        self._thread.start()

    def describe(self) -> DeviceInfo:
        return DeviceInfo(kind="load_cell", model="line-printing load-cell board", url=self.url,
                          channels=tuple(ChannelInfo(n, n.rsplit("_", 1)[-1], 0.0)
                                         for n in self.names),
                          extra={"separator": self.layout.separator})

    def _read(self) -> None:
        while not self._stop.is_set():
            try:
                data = read_some(self.port, self.url)
            except DeviceError as exc:
                with self._lock:
                    self._error = exc
                return
            if not data:
                continue
            now = self.clock.now()
            lines = self.decoder.feed(data)
            if lines:
                with self._lock:
                    self._rows += [(now, *(ln.values[n] for n in self.names)) for ln in lines]
                    self._last = now

    def read_block(self) -> Block:
        now = self.clock.now()
        with self._lock:
            rows, self._rows = self._rows, []
            err, last = self._error, self._last
        if err is not None:
            raise err
        if now - last > self.stale_s:
            raise DeviceError(f"{self.url}: no data line for {now - last:.3f} s "
                              f"(skipped {self.decoder.stats.skipped_lines} text lines, "
                              f"{self.decoder.stats.malformed} malformed)")
        if not rows:
            return Block.empty(self.names)
        arr = np.array(rows, dtype=float)
        return Block(arr[:, 0], {n: arr[:, k + 1] for k, n in enumerate(self.names)})

    def close(self) -> None:
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join(timeout=1.0)
