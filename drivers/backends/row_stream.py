"""Sensors whose rows arrive on a thread and leave through ``read_block``.

``block_from_rows`` turns buffered rows ``(t_s, value, ...)`` into a ``Block``.
``SerialStreamSensor`` is the shared part of the sensors that decode a continuous serial
stream (GX3 IMU, line-printing load-cell board): a reader thread stamps each decoded row
with the rig clock at reception; ``read_block`` hands over the rows, re-raises a read
error from the thread and raises while the device has been silent for over ``stale_s``.

Silence is the reader's finding, not the time since it last decoded a row: the reader may
itself be late (a busy host leaves a runnable thread off the processor for tenths of a
second), and the device's packets then wait in the port's buffer. A read begun at ``t``
that decodes nothing shows that no whole packet came between the last one and ``t``: only
such a read judges the device silent, for ``t`` minus the last packet's arrival.
"""

from __future__ import annotations

import threading
from collections.abc import Sequence
from typing import Any

import numpy as np

from drivers.backends.serial_link import read_some
from drivers.codecs.stream import link_losses
from drivers.contracts import Block, Clock, MonotonicClock
from drivers.errors import DeviceError

__all__ = ["SerialStreamSensor", "block_from_rows"]


def block_from_rows(rows: Sequence[tuple[float, ...]], names: tuple[str, ...]) -> Block:
    """Rows ``(t_s, *values in the order of names)`` as one block."""
    if not rows:
        return Block.empty(names)
    arr = np.array(rows, dtype=float)
    return Block(arr[:, 0], {n: arr[:, k + 1] for k, n in enumerate(names)})


class SerialStreamSensor:
    """Base of the streaming serial sensors. A subclass sets ``names`` and calls
    ``_start_reader`` once the device streams, and fills in ``_decode`` and ``_silence``."""

    names: tuple[str, ...]

    def __init__(self, port: Any, *, clock: Clock | None, stale_s: float, url: str) -> None:
        self.port = port
        self.clock = clock or MonotonicClock()
        self.stale_s = stale_s
        self.url = url
        self._rows: list[tuple[float, ...]] = []
        self._error: DeviceError | None = None
        self._silent_s: float | None = None  # the reader's finding; None while streaming
        self._last = self.clock.now()
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    def _decode(self, data: bytes, now: float) -> list[tuple[float, ...]]:
        """The rows ``(now, *values)`` decoded from one chunk of the stream."""
        raise NotImplementedError

    def _silence(self, silent_s: float) -> str:
        """The error message for a stream silent for ``silent_s``."""
        raise NotImplementedError

    def _start_reader(self, name: str) -> None:
        self._thread = threading.Thread(target=self._read, name=name, daemon=True)
        self._thread.start()

    def _read(self) -> None:
        while not self._stop.is_set():
            looked = self.clock.now()  # what came before this is in the read below
            try:
                data = read_some(self.port, self.url)
            except DeviceError as exc:
                with self._lock:
                    self._error = exc
                return
            now = self.clock.now()
            rows = self._decode(data, now) if data else []
            with self._lock:
                if rows:
                    self._rows += rows
                    self._last, self._silent_s = now, None
                elif looked - self._last > self.stale_s:
                    self._silent_s = looked - self._last

    def link_errors(self) -> dict[str, int]:
        """Frames lost on the link so far (bad checksums, truncated, malformed ...)."""
        decoder = getattr(self, "decoder", None)
        return link_losses(decoder.stats) if decoder is not None else {}

    def read_block(self) -> Block:
        with self._lock:
            rows, self._rows = self._rows, []
            err, silent = self._error, self._silent_s
        if err is not None:
            raise err
        if silent is not None:
            raise DeviceError(self._silence(silent))
        if self._thread is not None and not self._thread.is_alive():
            raise DeviceError(f"{self.url}: the reader thread stopped")
        return block_from_rows(rows, self.names)

    def close(self) -> None:
        self._stop.set()
        if self._thread is not None and self._thread.is_alive():
            self._thread.join(timeout=1.0)
