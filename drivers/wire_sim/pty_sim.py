"""The face every simulated serial device shows: a pty path to open, start and stop.

A simulator builds its :class:`~drivers.wire_sim.pty_port.PtyDevice` as ``self.port``
with its own ``handle`` (and ``tick`` for continuous streams); this base gives the driver
side ``path`` and the lifecycle.
"""

from __future__ import annotations

from typing import Self

from drivers.wire_sim.pty_port import PtyDevice

__all__ = ["PtySimulator"]


class PtySimulator:
    """Base of the simulators on a pseudo-terminal (``port`` set by the subclass)."""

    port: PtyDevice

    @property
    def path(self) -> str:
        """What the driver opens, like a real serial port."""
        return self.port.path

    def start(self) -> Self:
        self.port.start()
        return self

    def stop(self) -> None:
        self.port.stop()
