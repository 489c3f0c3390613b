"""One sensor device serving several rig roles (a board printing thrust, speed and power).

A load-cell board that prints thrust, rpm, volts and amps on one line, or a VESC whose
status broadcasts carry speed, current and voltage, is one device but fills the
``load_cell``, ``rpm`` and ``power`` roles of a rig. :class:`SharedSensor` reads the device
once per poll and fans the rows out; each :class:`RoleView` hands out the samples since
*its* previous read, restricted to its own columns (the runner needs each column to come
from exactly one role).
"""

from __future__ import annotations

import threading
from dataclasses import replace

import numpy as np

from drivers.contracts import Block, DeviceInfo, Sensor
from drivers.errors import DeviceError

__all__ = ["RoleView", "SharedSensor"]


class SharedSensor:
    """Fan-out of one device's blocks to per-role queues; closes the device with the last."""

    def __init__(self, device: Sensor) -> None:
        self.device = device
        self.names = tuple(c.name for c in device.describe().channels)
        self._queues: dict[str, list[Block]] = {}
        self._lock = threading.Lock()
        self._closed = False

    def view(self, role: str, names: tuple[str, ...]) -> RoleView:
        missing = [n for n in names if n not in self.names]
        if missing:
            url = self.device.describe().url
            raise DeviceError(f"{role}: {url} has no column {', '.join(map(repr, missing))} "
                              f"(it gives {', '.join(self.names)})")
        with self._lock:
            if role in self._queues:
                raise DeviceError(f"{role}: already has a view of {self.device.describe().url}")
            self._queues[role] = []
        return RoleView(self, role, names)

    def take(self, role: str) -> Block:
        with self._lock:
            block = self.device.read_block()  # errors reach every role that reads
            if len(block):
                for q in self._queues.values():
                    q.append(block)
            chunks, self._queues[role] = self._queues[role], []
        if not chunks:
            return Block.empty(self.names)
        if len(chunks) == 1:
            return chunks[0]
        return Block(np.concatenate([c.t_s for c in chunks]),
                     {n: np.concatenate([c.values[n] for c in chunks]) for n in self.names})

    def release(self, role: str) -> None:
        with self._lock:
            self._queues.pop(role, None)
            last = not self._queues and not self._closed
            if last:
                self._closed = True
        if last:
            self.device.close()


class RoleView:
    """The columns ``names`` of a shared device as one role's ``Sensor``."""

    def __init__(self, shared: SharedSensor, role: str, names: tuple[str, ...]) -> None:
        self.shared = shared
        self.role = role
        self.names = names
        self._closed = False

    def describe(self) -> DeviceInfo:
        info = self.shared.device.describe()
        by_name = {c.name: c for c in info.channels}
        chans = tuple(by_name[n] for n in self.names)
        return replace(info, kind=self.role, channels=chans,
                       extra={**info.extra, "shared_by_roles": True})

    def read_block(self) -> Block:
        if self._closed:
            raise DeviceError(f"{self.role}: sensor is closed")
        b = self.shared.take(self.role)
        return Block(b.t_s, {n: b.values[n] for n in self.names})

    def close(self) -> None:
        if not self._closed:
            self._closed = True
            self.shared.release(self.role)
