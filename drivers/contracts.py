"""Device contracts: the small protocols every backend (real, simulated, replayed) fills.

A sensor hands out timestamped blocks of samples; an actuator takes commands and
always knows how to make itself safe. Column names carry their unit
(``thrust_n``, ``current_a``, ``voltage_v``, ``rpm``, ``throttle_us``), so blocks can
go straight into a run record. Timestamps are seconds on the rig clock.
"""

from __future__ import annotations

import enum
import time
from dataclasses import dataclass, field
from typing import Protocol, runtime_checkable

import numpy as np


@dataclass(frozen=True)
class ChannelInfo:
    """One recorded column: its name (with unit suffix), unit, rate and valid range."""

    name: str
    unit: str
    rate_hz: float
    low: float = -np.inf
    high: float = np.inf


@dataclass(frozen=True)
class DeviceInfo:
    """What a device is and what it produces or accepts."""

    kind: str  # "load_cell", "power_sensor", "rpm_sensor", "esc", "hexapod", "imu", ...
    model: str
    url: str
    channels: tuple[ChannelInfo, ...] = ()
    extra: dict[str, object] = field(default_factory=dict)


@dataclass(frozen=True)
class Block:
    """Samples that arrived since the previous read: ``t_s`` and one array per channel."""

    t_s: np.ndarray
    values: dict[str, np.ndarray]

    def __len__(self) -> int:
        return int(self.t_s.shape[0])

    @staticmethod
    def empty(names: tuple[str, ...]) -> Block:
        return Block(np.empty(0), {n: np.empty(0) for n in names})


class Clock(Protocol):
    """Rig time. Real rigs use the host's monotonic clock; the simulated rig its own."""

    def now(self) -> float: ...

    def sleep(self, seconds: float) -> None: ...


@runtime_checkable
class Sensor(Protocol):
    """A device that produces timestamped blocks (load cell, power sensor, RPM sensor, IMU)."""

    def describe(self) -> DeviceInfo: ...

    def read_block(self) -> Block:
        """Return every sample that arrived since the last call (possibly none).

        Raises ``drivers.errors.DeviceError`` when the device is gone or timed out.
        """
        ...

    def close(self) -> None: ...


@runtime_checkable
class Esc(Protocol):
    """The ESC's command input: pulse width in microseconds at a fixed frame rate."""

    def describe(self) -> DeviceInfo: ...

    def arm(self) -> None: ...

    def set_pulse_us(self, pulse_us: float) -> None:
        """Command a pulse width (clamped by the caller's limits, 1000-2000 us)."""
        ...

    def disarm(self) -> None:
        """Command idle and disarm. Must be safe to call at any time, repeatedly."""
        ...

    def close(self) -> None: ...


class Fault(enum.Enum):
    """Fault switches a simulated (or test) device can be set to, see ``drivers.sim.faults``.

    DROPOUT: samples go missing; SPIKES: single samples jump to full scale; STUCK: the
    reading freezes; TIMEOUT: reads/commands raise ``DeviceError`` while it lasts;
    DISCONNECT: the device is gone until cleared (reads/commands raise ``DeviceError``).
    """

    DROPOUT = "dropout"
    SPIKES = "spikes"
    STUCK = "stuck"
    TIMEOUT = "timeout"
    DISCONNECT = "disconnect"


class MonotonicClock:
    """Real rig time: the host's monotonic clock, zero at construction.

    ``sleep`` really waits; the simulated rig uses ``drivers.sim.clock.SimClock`` instead.
    """

    def __init__(self) -> None:
        self._t0 = time.monotonic()

    def now(self) -> float:
        return time.monotonic() - self._t0

    def sleep(self, seconds: float) -> None:
        if seconds > 0:
            time.sleep(seconds)
