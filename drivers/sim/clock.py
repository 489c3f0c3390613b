"""Simulated rig time: ``sleep`` advances the plant instead of waiting.

Time is kept in integer nanoseconds so that ESC frames, sensor samples and commands
line up exactly however the caller slices its sleeps (no float drift deciding whether a
command makes it into a frame).
"""

from __future__ import annotations

from collections.abc import Callable

from drivers.errors import DeviceError


class SimClock:
    """A clock whose ``sleep(dt)`` moves simulated time forward and runs the listeners."""

    def __init__(self) -> None:
        self._t_ns = 0
        self._listeners: list[Callable[[int], None]] = []

    def now(self) -> float:
        return self._t_ns * 1e-9

    def now_ns(self) -> int:
        return self._t_ns

    def sleep(self, seconds: float) -> None:
        if seconds != seconds:  # NaN
            raise DeviceError(f"sim clock: cannot sleep {seconds!r} s")
        self._t_ns += max(0, round(seconds * 1e9))  # like a real clock: <= 0 returns at once
        for listener in self._listeners:
            listener(self._t_ns)

    def snapshot(self) -> int:
        return self._t_ns

    def restore(self, snap: int) -> None:
        """Set the time back to a ``snapshot`` (a simulated rig's checkpoint)."""
        self._t_ns = snap

    def on_advance(self, listener: Callable[[int], None]) -> None:
        """Call ``listener(now_ns)`` after every sleep (the rig tells its plant the time
        here; the plant integrates when it is looked at)."""
        self._listeners.append(listener)
