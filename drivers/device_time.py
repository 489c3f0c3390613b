"""Rows stamped with the device's own clock, mapped onto the host clock.

A line-printing board stamps each line when it reads the load cell (TestStand v2 prints
``Time(uS)``, Arduino ``micros()``); the host sees the line later, by a delay that varies
with USB polling and with how busy the host is. Stamping rows on reception puts that
jitter into the data (a step looks smeared and slower); the device's stamps do not have
it. The offset between the clocks is estimated as the smallest ``host reception - device
time`` over the last ``window_s`` (the least-delayed lines; a sliding window follows a
slow crystal drift), applied per block, and the stamps never run backwards.
"""

from __future__ import annotations

import math
from collections import deque

import numpy as np

from drivers.contracts import Block, DeviceInfo, Sensor
from drivers.errors import DeviceError

__all__ = ["MICROS_WRAP_S", "DeviceTimeSensor"]

MICROS_WRAP_S = 2**32 * 1e-6  # Arduino micros() wraps after 71.6 min


class DeviceTimeSensor:
    """``sensor``'s rows re-stamped from its ``column`` of device time (seconds)."""

    def __init__(self, sensor: Sensor, column: str = "t_s", *, window_s: float = 2.0,
                 wrap_s: float = MICROS_WRAP_S) -> None:
        names = [c.name for c in sensor.describe().channels]
        if column not in names:
            raise DeviceError(f"{sensor.describe().url}: device time stamps need a {column!r} "
                              f"column in the line layout (it has {', '.join(names)})")
        self.sensor = sensor
        self.column = column
        self.window_s = window_s
        self.wrap_s = wrap_s
        self._offsets: deque[tuple[float, float]] = deque()  # (host time, block min offset)
        self._wraps = 0
        self._prev_raw = -math.inf
        self._last_t = -math.inf

    def describe(self) -> DeviceInfo:
        info = self.sensor.describe()
        return DeviceInfo(info.kind, info.model, info.url, info.channels,
                          {**info.extra, "time_stamps": f"device ({self.column})"})

    def _unwrap(self, raw: np.ndarray) -> np.ndarray:
        prev = np.concatenate(([self._prev_raw], raw[:-1]))
        wraps = self._wraps + np.cumsum(raw - prev < -0.5 * self.wrap_s)
        self._wraps, self._prev_raw = int(wraps[-1]), float(raw[-1])
        return raw + wraps * self.wrap_s

    def read_block(self) -> Block:
        block = self.sensor.read_block()
        if len(block) == 0:
            return block
        dev = self._unwrap(np.asarray(block.values[self.column], float))
        host = block.t_s
        now = float(host[-1])
        self._offsets.append((now, float(np.min(host - dev))))
        while self._offsets and self._offsets[0][0] < now - self.window_s:
            self._offsets.popleft()
        offset = min(o for _, o in self._offsets)
        t = np.maximum.accumulate(np.maximum(dev + offset, self._last_t))
        self._last_t = float(t[-1])
        return Block(t, block.values)

    def close(self) -> None:
        self.sensor.close()
