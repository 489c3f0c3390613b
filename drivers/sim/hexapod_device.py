"""Simulated hexapod device: runs uploaded trajectories exactly and logs the body-frame truth.

The platform follows the cubic spline through the uploaded poses (zero velocity at both
ends, i.e. it starts and ends at rest) on the simulated rig clock; between trajectories
it rests where the last one ended or where ``stop`` froze it. A trajectory that would
exceed a limit, or that does not start at the present pose, is refused at upload. The
controller's log runs at ``log_rate_hz`` from the moment the device is opened; the body-
frame quantities come from :mod:`drivers.hexapod_kinematics` (the same physics as
:class:`drivers.sim.hexapod.SimHexapod`). Faults (timeout, disconnect, spikes, dropout,
stuck) are switches as on every simulated device.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Unpack

import numpy as np
from numpy.typing import NDArray
from scipy.interpolate import CubicSpline

from drivers.contracts import (
    HEXAPOD_LOG_CHANNELS,
    Block,
    ChannelInfo,
    DeviceInfo,
    Fault,
    HexapodLimits,
    Trajectory,
)
from drivers.errors import DeviceError
from drivers.hexapod_kinematics import (
    GRAVITY_M_S2,
    HexapodState,
    body_frame_state,
)
from drivers.hexapod_log import checked_spline, log_block
from drivers.sim.clock import SimClock
from drivers.sim.faults import FaultOptions, FaultSwitches

__all__ = ["SimHexapodDevice"]

Array = NDArray[np.float64]
_START_TOLERANCE = 1e-6  # m or rad between the present pose and a trajectory's first pose


@dataclass
class _Run:
    """One started trajectory on the rig clock."""

    name: str
    t0: float
    spline: CubicSpline
    duration: float
    stopped_at: float = math.inf
    end_pose: Array | None = None  # pose at rest after the run (cached)
    end_at: float = math.nan

    @property
    def t_end(self) -> float:
        # the earlier of the two end times, not t0 + min(duration, stopped_at - t0): in
        # floating point t0 + (stopped_at - t0) can exceed stopped_at by an ulp (t0 =
        # 1.08231501, stopped at 3.883613346 gives 3.8836133460000006), and a platform
        # stopped at X then still "moved" at X, which a paused bench clock reads again
        return min(self.t0 + self.duration, self.stopped_at)


class SimHexapodDevice:
    """The ``sim://hexapod`` device (see module docstring)."""

    def __init__(self, clock: SimClock, limits: HexapodLimits | None = None, *,
                 log_rate_hz: float = 1000.0, rng: np.random.Generator | None = None,
                 gravity: float = GRAVITY_M_S2, url: str = "sim://hexapod") -> None:
        self.clock = clock
        self._limits = limits or HexapodLimits()
        self.log_rate_hz = float(log_rate_hz)
        self.gravity = gravity
        self.url = url
        self.pivot_m = (0.0, 0.0, 0.0)
        self.faults = FaultSwitches("sim hexapod", rng or np.random.default_rng(0),
                                    tuple(Fault))
        self._runs: list[_Run] = []
        self._uploaded: tuple[Trajectory, CubicSpline] | None = None
        self._next_k = math.floor(clock.now() * self.log_rate_hz) + 1
        self.stop_calls = 0
        self.closed = False
        # counts starts and stops: truth computed ahead of time (a simulated sensor's block
        # of readings, drivers.wire_sim.grid_sampler) holds while it is unchanged
        self.motion_version = 0

    # -- truth --------------------------------------------------------------------------
    def kinematics_at(self, t_s: Array) -> tuple[Array, Array, Array]:
        """Pose, velocity and acceleration ``(n, 6)`` at rig times ``t_s``."""
        t = np.atleast_1d(np.asarray(t_s, dtype=float))
        pose = np.zeros((t.size, 6))
        vel = np.zeros_like(pose)
        acc = np.zeros_like(pose)
        if t.size == 0 or not self._runs:
            return pose, vel, acc
        # Runs never overlap (start is refused while moving) and a later run overrides an
        # earlier one from its start on: only the runs back to the first one that ended
        # before min(t) matter.
        lo = float(t.min())
        first = len(self._runs) - 1
        while first > 0 and self._runs[first].t0 > lo:
            first -= 1
        for run in self._runs[first:]:
            after = t >= run.t0
            if not after.any():
                continue
            inside = after & (t < run.t_end)
            rest = after & ~inside
            if inside.any():
                u = t[inside] - run.t0
                pose[inside] = run.spline(u)
                vel[inside] = run.spline(u, 1)
                acc[inside] = run.spline(u, 2)
            if rest.any():
                if run.end_pose is None or run.end_at != run.t_end:
                    run.end_pose, run.end_at = run.spline(run.t_end - run.t0), run.t_end
                pose[rest] = run.end_pose
                vel[rest] = 0.0
                acc[rest] = 0.0
        return pose, vel, acc

    def state_at(self, t_s: Array) -> HexapodState:
        """Body-frame truth (rate, angular acceleration, specific force at the pivot)."""
        t = np.atleast_1d(np.asarray(t_s, dtype=float))
        pose, vel, acc = self.kinematics_at(t)
        return body_frame_state(t, pose, vel, acc, self.gravity)

    # -- contract -----------------------------------------------------------------------
    def describe(self) -> DeviceInfo:
        units = {"_m": "m", "_rad": "rad", "_m_s": "m/s", "_rad_s": "rad/s", "_m_s2": "m/s^2",
                 "_rad_s2": "rad/s^2"}

        def unit(name: str) -> str:
            return next(u for k, u in sorted(units.items(), key=lambda kv: -len(kv[0]))
                        if name.endswith(k))

        return DeviceInfo(
            kind="hexapod", model="simulated hexapod (exact follower)", url=self.url,
            channels=tuple(ChannelInfo(c, unit(c), self.log_rate_hz)
                           for c in HEXAPOD_LOG_CHANNELS),
            extra={"limits": self._limits.as_dict(), "pivot_m": list(self.pivot_m),
                   "log_rate_hz": self.log_rate_hz},
        )

    def limits(self) -> HexapodLimits:
        return self._limits

    def is_moving(self) -> bool:
        now = self.clock.now()
        return any(r.t0 <= now < r.t_end for r in self._runs)

    def set_pivot(self, pivot_m: tuple[float, float, float]) -> None:
        self._check("set_pivot")
        if self.is_moving():
            raise DeviceError("sim hexapod: setting the pivot point is not possible while "
                              "moving")
        p = tuple(float(v) for v in pivot_m)
        if len(p) != 3 or not all(math.isfinite(v) for v in p):
            raise DeviceError(f"sim hexapod: pivot must be three finite numbers (m), got "
                              f"{pivot_m!r}")
        self.pivot_m = p  # type: ignore[assignment]

    def upload(self, trajectory: Trajectory) -> None:
        self._check("upload")
        now = self.clock.now()
        here, _, _ = self.kinematics_at(np.array([now]))
        jump = float(np.abs(trajectory.poses[0] - here[0]).max())
        if jump > _START_TOLERANCE:
            raise DeviceError(f"sim hexapod: trajectory {trajectory.name!r} starts {jump:.4g} "
                              "(m or rad) away from the present pose; refused")
        spline = checked_spline(trajectory, self._limits, self.gravity, "sim hexapod")
        self._uploaded = (trajectory, spline)

    def start(self) -> None:
        self._check("start")
        if self._uploaded is None:
            raise DeviceError("sim hexapod: start without an uploaded trajectory")
        if self.is_moving():
            raise DeviceError("sim hexapod: start refused while a trajectory runs")
        traj, spline = self._uploaded
        self._uploaded = None
        self._runs.append(_Run(traj.name, self.clock.now(), spline, traj.duration_s))
        self.motion_version += 1

    def read_log(self) -> Block:
        now = self.clock.now()
        self._check("read_log")
        k_end = math.floor(now * self.log_rate_hz + 1e-9)
        if k_end < self._next_k:
            return Block.empty(HEXAPOD_LOG_CHANNELS)
        t = np.arange(self._next_k, k_end + 1) / self.log_rate_hz
        self._next_k = k_end + 1
        pose, vel, acc = self.kinematics_at(t)
        full = dict.fromkeys(HEXAPOD_LOG_CHANNELS, 1e3)  # a spike: far beyond any limit
        return self.faults.apply(log_block(t, pose, vel, acc, self.gravity), full)

    def stop(self) -> None:
        """Freeze the platform where it is (an abrupt #24-style stop); never refused."""
        self.stop_calls += 1
        now = self.clock.now()
        for run in self._runs:
            if run.t0 <= now < run.t_end:
                run.stopped_at = now
        self.motion_version += 1
        self._uploaded = None
        self.faults.check(now, "stop")  # the platform is stopped; the reply may be lost

    def close(self) -> None:
        try:
            self.stop()
        except DeviceError:
            pass
        self.closed = True

    def inject(self, fault: Fault | str, **kwargs: Unpack[FaultOptions]) -> None:
        self.faults.inject(fault, **kwargs)

    def _check(self, what: str) -> None:
        if self.closed:
            raise DeviceError(f"sim hexapod: {what} after close")
        self.faults.check(self.clock.now(), what)
