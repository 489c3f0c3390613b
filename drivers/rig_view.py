"""What drivers read of a rig file: the validated rig config, seen as a protocol.

The bench loads and validates rig files (``bench.rig.rig.RigConfig``); ``drivers`` must not
import ``bench`` (the floors of docs/architecture.md), so the openers and simulated worlds
take any object of this shape. ``RigConfig`` and its sections fit it structurally; so do
the small stand-ins of the tests.

Members are read-only properties: a frozen dataclass field satisfies them.

A rig carries the sections of its own bench only (the others are None): the propulsion
stand's ``esc`` and :class:`PropulsionSimView`; the IMU bench's ``hexapod``, ``imu``,
``reference_imu`` and :class:`ImuSimView`. :func:`section`, :func:`propulsion_sim` and
:func:`imu_sim` hand out the one a driver needs, or say which table the rig lacks.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from typing import Any, Protocol, TypeVar, runtime_checkable

from drivers.contracts import HexapodLimits
from drivers.errors import DeviceError

__all__ = ["DeviceView", "EscView", "HexapodView", "ImuSimView", "ImuView",
           "PropulsionSimView", "RigView", "imu_sim", "propulsion_sim", "section"]

T = TypeVar("T")


class DeviceView(Protocol):
    """One ``[devices.<role>]`` table: where the device is and how to read it."""

    @property
    def url(self) -> str: ...
    @property
    def channel(self) -> str: ...
    @property
    def calibration(self) -> Mapping[str, float]: ...
    @property
    def options(self) -> Mapping[str, Any]: ...


class EscView(Protocol):
    """The propulsion stand's ``[esc]`` table: pulse range and timing (µs, Hz, s)."""

    @property
    def frame_rate_hz(self) -> float: ...
    @property
    def idle_us(self) -> float: ...
    @property
    def min_us(self) -> float: ...
    @property
    def max_us(self) -> float: ...
    @property
    def arm_us(self) -> float: ...
    @property
    def timeout_s(self) -> float: ...


@runtime_checkable
class PropulsionSimView(Protocol):
    """The propulsion stand's ``[sim]`` table: seed, ESC scheme, model overrides."""

    @property
    def seed(self) -> int: ...
    @property
    def esc_mode(self) -> str: ...
    @property
    def noise(self) -> bool: ...
    @property
    def plant(self) -> Mapping[str, float]: ...
    @property
    def sensors(self) -> Mapping[str, float]: ...


@runtime_checkable
class ImuSimView(Protocol):
    """The IMU bench's ``[sim]`` table: seed, noise, true centre of gravity, IMU errors."""

    @property
    def seed(self) -> int: ...
    @property
    def noise(self) -> bool: ...
    @property
    def cg_m(self) -> tuple[float, float, float] | None: ...
    @property
    def imu(self) -> Mapping[str, Any]: ...


class HexapodView(Protocol):
    """The IMU bench's ``[hexapod]`` table."""

    @property
    def limits(self) -> Mapping[str, float]: ...
    @property
    def pivot_m(self) -> tuple[float, float, float]: ...
    @property
    def log_rate_hz(self) -> float: ...
    def hexapod_limits(self) -> HexapodLimits: ...


class ImuView(Protocol):
    """The IMU bench's ``[imu]`` table: the model's parameters."""

    @property
    def params(self) -> Mapping[str, Any]: ...
    def value(self, name: str) -> float: ...


class RigView(Protocol):
    """A validated rig file, of either bench, as the drivers read it."""

    @property
    def path(self) -> str | os.PathLike[str]: ...
    @property
    def devices(self) -> Mapping[str, DeviceView]: ...
    @property
    def esc(self) -> EscView | None: ...
    @property
    def sim(self) -> PropulsionSimView | ImuSimView | None: ...
    @property
    def hexapod(self) -> HexapodView | None: ...
    @property
    def imu(self) -> ImuView | None: ...
    @property
    def reference_imu(self) -> Mapping[str, float] | None: ...


def section(rig: RigView, value: T | None, table: str) -> T:
    """``value``, a section of ``rig``; a rig of the other bench has none: DeviceError."""
    if value is None:
        raise DeviceError(f"{rig.path}: no [{table}] table (a rig of the other bench?)")
    return value


def propulsion_sim(rig: RigView) -> PropulsionSimView:
    """The propulsion stand's ``[sim]`` table of ``rig``."""
    sim = rig.sim
    if not isinstance(sim, PropulsionSimView):
        raise DeviceError(f"{rig.path}: [sim] is not a propulsion stand's")
    return sim


def imu_sim(rig: RigView) -> ImuSimView:
    """The IMU bench's ``[sim]`` table of ``rig``."""
    sim = rig.sim
    if not isinstance(sim, ImuSimView):
        raise DeviceError(f"{rig.path}: [sim] is not an IMU bench's")
    return sim
