"""A simulated sensor's readings on its own sample grid, computed a block at a time.

Why: a device simulator that answers each poll with one freshly computed sample pays
numpy's per-call cost for every reading (the hexapod truth, the sensor model and its noise
for one sample took 0.4 ms here, at 6x about 1 000 readings a second of wall time: most of a
simulated IMU bench's process); computed for a block of grid times in one call, a reading
costs microseconds. A real sensor samples on its own clock too: a flight controller's MSP
reply carries its latest loop sample, a 3DM-GX3 streams on its timer's grid.

The readings follow the plant's motion, which a command can change at any moment (a
trajectory started or stopped, the pivot moved). A block is kept only while ``version()``
returns what it returned before the block was computed; read first, so a change during the
computation makes the next reading compute again. :meth:`GridSampler.prefetch`, called
between requests, computes the next block before a reading needs it, so a reply rarely
waits for a block.
"""

from __future__ import annotations

import math
import threading
from collections.abc import Callable, Hashable

import numpy as np
from numpy.typing import NDArray

__all__ = ["GridSampler"]

Rows = Callable[[NDArray[np.float64]], NDArray[np.float64]]


class GridSampler:
    """Rows of ``compute(times) -> (n, m)`` at ``origin_s + k * period_s``, ``block`` at a
    time (see module doc); thread-safe."""

    def __init__(self, compute: Rows, period_s: float, *, origin_s: float = 0.0,
                 block: int = 100, version: Callable[[], Hashable] = lambda: None) -> None:
        if not (period_s > 0 and block >= 1):
            raise ValueError(f"grid sampler: period {period_s!r} s, block {block!r}")
        self.compute, self.period_s, self.origin_s = compute, float(period_s), float(origin_s)
        self.block, self.version = int(block), version
        self._lock = threading.Lock()
        self._key: Hashable = object()  # matches no version: the first reading computes
        self._k0 = 0
        self._rows: list[list[float]] = []
        self.blocks_computed = 0

    def index_at(self, t_s: float) -> int:
        """The grid sample taken last at or before ``t_s`` (a sample-and-hold reading)."""
        return math.floor((t_s - self.origin_s) / self.period_s + 1e-9)

    def time_of(self, k: int) -> float:
        return self.origin_s + k * self.period_s

    def row(self, k: int) -> list[float]:
        """Grid sample ``k``'s row."""
        with self._lock:
            key = self.version()
            if key != self._key or not self._k0 <= k < self._k0 + len(self._rows):
                self._fill(k, key)
            return self._rows[k - self._k0]

    def at(self, t_s: float) -> list[float]:
        """The row of the grid sample taken last at or before ``t_s``."""
        return self.row(self.index_at(t_s))

    def prefetch(self, t_s: float) -> None:
        """Compute the block after the present one once ``t_s`` is in its second half (or
        the present one anew when the plant changed): between requests, off a reply's path."""
        k = self.index_at(t_s)
        with self._lock:
            key = self.version()
            if key != self._key or not self._k0 <= k < self._k0 + len(self._rows) - self.block // 2:
                self._fill(k, key)

    def _fill(self, k: int, key: Hashable) -> None:
        times = self.origin_s + np.arange(k, k + self.block, dtype=np.float64) * self.period_s
        self._rows = np.asarray(self.compute(times), dtype=float).tolist()
        self._k0, self._key = k, key
        self.blocks_computed += 1
