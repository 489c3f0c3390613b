"""The one module that imports python-can: a bus wrapped as frames in, frames out.

``CanLink`` turns ``can.Message`` into ``drivers.codecs.can_log.CanFrame`` at the edge,
runs python-can's ``Notifier`` (its reader thread) and hands every received frame to the
subscribers. Sending errors become ``DeviceError``; the link never closes the bus it was
given (whoever opened the bus shuts it down).
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from typing import Any

import can

from drivers.codecs.can_log import CanFrame
from drivers.errors import DeviceError

Subscriber = Callable[[CanFrame], None]


def detect_configs(interface: str) -> list[tuple[str, str]]:
    """(interface, channel) pairs python-can detects on one interface."""
    configs = can.detect_available_configs(interfaces=[interface])
    return [(str(c.get("interface", interface)), str(c.get("channel", ""))) for c in configs]


def open_bus(interface: str, channel: str, **kwargs: Any) -> can.BusABC:
    """``can.Bus`` with errors turned into ``DeviceError`` naming interface and channel."""
    try:
        return can.Bus(interface=interface, channel=channel, **kwargs)
    except (can.CanError, OSError, ValueError, ImportError) as exc:
        raise DeviceError(f"can://{interface}/{channel}: cannot open the bus ({exc})") from None


class CanLink:
    """Frames from/to one bus; ``subscribe`` callbacks run on python-can's reader thread."""

    def __init__(self, bus: can.BusABC, name: str = "can") -> None:
        self.bus = bus
        self.name = name
        self._subs: list[Subscriber] = []
        self._lock = threading.Lock()
        self._notifier = can.Notifier(bus, [self._on_message], timeout=0.02)
        self._closed = False

    def subscribe(self, callback: Subscriber) -> None:
        with self._lock:
            self._subs.append(callback)

    def unsubscribe(self, callback: Subscriber) -> None:
        with self._lock:
            if callback in self._subs:
                self._subs.remove(callback)

    def _on_message(self, msg: can.Message) -> None:
        if msg.is_error_frame or msg.is_remote_frame:
            return
        frame = CanFrame(msg.arbitration_id, bytes(msg.data), msg.is_extended_id,
                         float(msg.timestamp or 0.0), str(msg.channel or ""))
        with self._lock:
            subs = list(self._subs)
        for cb in subs:
            cb(frame)

    def send(self, frame: CanFrame) -> None:
        if self._closed:
            raise DeviceError(f"{self.name}: link is closed")
        msg = can.Message(arbitration_id=frame.arbitration_id, data=frame.data,
                          is_extended_id=frame.is_extended_id)
        try:
            self.bus.send(msg, timeout=0.05)
        except (can.CanError, OSError) as exc:
            raise DeviceError(f"{self.name}: CAN send failed ({exc})") from None

    def close(self) -> None:
        """Stop the reader thread (the bus stays open)."""
        if not self._closed:
            self._closed = True
            self._notifier.stop(timeout=0.5)
