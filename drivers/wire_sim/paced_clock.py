"""Simulated time on the wall clock, for the IMU bench's wire-level simulated devices.

:class:`PacedClock` runs the simulated IMU bench (:class:`drivers.sim.imu_rig.SimImuRig`:
hexapod plant, IMU model, reference) on the wall clock, ``time_scale`` simulated seconds
per wall second, so the backends' threads, timeouts and the pty's latency act on it as on
a bench; :class:`HeldUploads` keeps a trajectory upload from costing simulated time. Two
processes read one bench time from two clocks given the same ``epoch`` and no pauses
(``drivers.wire_sim.imu_world``).
"""

from __future__ import annotations

import contextlib
import math
import threading
import time
from collections.abc import Iterator
from typing import Any

from drivers.errors import DeviceError
from drivers.sim.clock import SimClock

__all__ = ["HeldUploads", "PacedClock"]


class PacedClock(SimClock):
    """Simulated time that runs ``time_scale`` times as fast as the wall clock.

    The simulated devices read it (a :class:`SimClock`); ``sleep`` waits on the wall
    clock. It has no listeners: the IMU bench's plant is evaluated at the times asked.
    ``hold()`` stops simulated time while the host uploads a trajectory (see
    :class:`HeldUploads`). When nobody has read the clock for more than ``max_gap_s`` of
    wall time (the simulated devices read it every few milliseconds, so the whole process
    was starved by a loaded machine), only ``max_gap_s`` counts: the simulated world
    pauses with the computer that simulates it instead of jumping ahead of its devices.
    """

    def __init__(self, time_scale: float = 1.0, *, max_gap_s: float = 0.02,
                 max_pause_s: float = 0.3, epoch: float | None = None) -> None:
        super().__init__()
        if not (math.isfinite(time_scale) and time_scale > 0):
            raise DeviceError(f"time_scale {time_scale!r}: expected a positive number")
        self.time_scale = float(time_scale)
        self.max_gap_s = float(max_gap_s)
        self._lock = threading.Lock()
        self._last_wall = time.monotonic()
        self._wall0 = self._last_wall if epoch is None else float(epoch)
        self._held: int | None = None
        self.max_pause_s = float(max_pause_s)
        self.paused_s = 0.0  # wall time not counted (starved process), for the record
        self._alive: dict[str, float] = {}
        self._pause_run = 0.0

    def alive(self, name: str) -> None:
        """A simulated device ``name`` served its host just now (see :meth:`now_ns`)."""
        self._alive[name] = time.monotonic()

    def now_ns(self) -> int:
        """Bench time. It does not advance through wall time nobody read it in (a starved
        process), nor while a simulated device that reports :meth:`alive` has been quiet
        for over ``max_gap_s`` (its thread, or the host thread it serves, is starved),
        for at most ``max_pause_s`` of wall time in a row: a device that really went
        silent still goes stale on the bench clock soon after."""
        with self._lock:
            if self._held is not None:
                return self._held
            wall = time.monotonic()
            gap = wall - self._last_wall
            quiet = wall - min(self._alive.values(), default=wall)
            if quiet > self.max_gap_s and self._pause_run < self.max_pause_s:
                lost = min(gap, self.max_pause_s - self._pause_run)
                self._pause_run += lost
            else:
                lost = max(0.0, gap - self.max_gap_s)
                if quiet <= self.max_gap_s:
                    self._pause_run = 0.0
            self._wall0 += lost
            self.paused_s += lost
            self._last_wall = wall
            return round((wall - self._wall0) * self.time_scale * 1e9)

    def now(self) -> float:
        return self.now_ns() * 1e-9

    def sleep(self, seconds: float) -> None:
        if seconds != seconds:  # NaN
            raise DeviceError(f"paced clock: cannot sleep {seconds!r} s")
        end = self.now() + seconds
        while (left := end - self.now()) > 0:  # wall slices: a starved pause is made up
            time.sleep(min(left / self.time_scale, self.max_gap_s / 2))

    def on_advance(self, listener: Any) -> None:
        raise DeviceError("paced clock: the plant runs on the wall clock; no listeners")

    @property
    def epoch(self) -> float:
        """The monotonic wall time at which bench time was 0 (pauses and holds move it)."""
        with self._lock:
            return self._wall0

    @contextlib.contextmanager
    def hold(self) -> Iterator[None]:
        """Simulated time stands still inside the block, then goes on from where it was."""
        self.freeze()
        try:
            yield
        finally:
            self.resume()

    def freeze(self, held_ns: int | None = None) -> int:
        """Bench time stands at ``held_ns`` (default: now) until :meth:`resume`; returns it.
        The halves of ``hold``, for a clock that another process's clock follows."""
        held = self.now_ns() if held_ns is None else int(held_ns)
        with self._lock:
            self._held = held
        return held

    def resume(self, epoch: float | None = None) -> float:
        """Bench time runs again: from the held time on (default), or from the monotonic
        wall time ``epoch`` of bench time 0; returns the epoch."""
        with self._lock:
            wall = time.monotonic()
            if epoch is None:
                held = self._held if self._held is not None else 0
                epoch = wall - held * 1e-9 / self.time_scale
            self._wall0 = float(epoch)
            self._last_wall = wall
            self._held = None
            return self._wall0


class HeldUploads:
    """A hexapod whose trajectory upload and start take no simulated time.

    Over a wire the upload (hundreds of GCS commands) takes wall time, which
    ``time_scale`` would multiply into seconds of bench time; the runner would follow
    (its time base starts at the start command) but the run would drift from the plain
    bench's timing. The plain and ``tcp://sim`` benches upload in zero simulated time;
    this keeps the serial wire bench the same (the hold lasts until the controller has
    answered a query after ``WGO``, so the motion starts at the held instant). On a real
    bench the upload's wall time is real: see docs/hexapod-tcp.md.
    """

    def __init__(self, hexapod: Any, clock: PacedClock) -> None:
        self._hexapod = hexapod
        self._clock = clock

    def upload(self, trajectory: Any) -> None:
        with self._clock.hold():
            self._hexapod.upload(trajectory)

    def start(self) -> None:
        with self._clock.hold():
            self._hexapod.start()
            self._hexapod.is_moving()  # a reply after WGO: the controller has started it

    def __getattr__(self, name: str) -> Any:
        return getattr(self._hexapod, name)
