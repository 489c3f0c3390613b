"""The simulated IMU bench as the Betaflight SITL's world: the hexapod's motion in FDM.

The firmware's virtual gyro and accelerometer read whatever the FDM packets carry
(betaflight-sitl.md §1.3), so the firmware becomes the IMU under test once the packets
carry what the IMU model of the rig (``drivers.sim.imu``: mounting, scale, axis
misalignment, lever arm, bias, noise, quantisation) measures on the simulated hexapod:
:meth:`drivers.sim.imu_device.SimImuDevice.sample_at`, the model's one home, sampled
``clock_offset_s`` before each packet's time. The model's axes are the firmware's
forward-left-up body axes (it reads +g up at rest, as Betaflight's RAW_IMU does), the
hexapod's z-up navigation frame is the east-north-up earth the bench's attitude tools use,
and the attitude sent is the platform's (the UAV body's): the SITL echoes it, as a
flight controller whose board alignment is the IMU's mounting would report it.

The model is sampled at the world's (paced) clock; the packets are stamped by
:func:`drivers.codecs.sitl.fdm_stamps`, as the propulsion world's: stamped with the clock
(1 ms apart) the firmware re-estimated its clock rate from each packet's wall-clock gap,
and a host stall's burst made its clock, and so its serial task, leap; by fixed
steps its clock is the host's monotonic one. Every call tells the clock the feeder is
alive (a starved process pauses the world instead of jumping it ahead).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation

from drivers.codecs.sitl import encode_fdm_imu, fdm_stamps

__all__ = ["HexapodFdm"]


class HexapodFdm:
    """``fdm(wall_t)``: the next FDM packet of ``world`` (a ``SimImuRig`` on a paced clock).

    The model is sampled ``batch`` packets ahead on a grid of ``step_s`` (one numpy call:
    ~25 us a packet instead of ~600 us one by one, which a loaded host could not give
    1000 times a second; the accelerometer's filter in the firmware advances once per
    packet, so the packet rate is its sample rate); each packet carries the latest grid
    sample at or before its time stamp, at most ``step_s`` old.
    """

    def __init__(self, world: Any, step_s: float = 0.001, batch: int = 20) -> None:
        self.world = world
        self.clock = world.clock
        self.step_s = float(step_s)
        self.batch = int(batch)
        self._alive = getattr(self.clock, "alive", None)
        self.last_t = -np.inf
        self._stamps = fdm_stamps()
        self._grid = np.empty(0)
        self._rows = np.empty((0, 10))  # gyro, specific force, quaternion per grid time

    def _sample(self, t: float) -> None:
        grid = t + self.step_s * np.arange(self.batch)
        truth, gyro, acc = self.world.imu.sample_at(grid)
        q = Rotation.from_euler("xyz", truth.euler_rad).as_quat(scalar_first=True)
        self._grid, self._rows = grid, np.hstack([gyro, acc, q])

    def __call__(self, _wall_t: float) -> bytes:
        if self._alive is not None:
            self._alive("sitl")
        t = self.last_t = max(self.clock.now(), self.last_t)
        if not (self._grid.size and self._grid[0] <= t < self._grid[-1] + self.step_s):
            self._sample(t)
        k = int(np.searchsorted(self._grid, t, side="right")) - 1
        gx, gy, gz, ax, ay, az, qw, qx, qy, qz = self._rows[k].tolist()
        return encode_fdm_imu(next(self._stamps), (gx, gy, gz), (ax, ay, az),
                              (qw, qx, qy, qz))
