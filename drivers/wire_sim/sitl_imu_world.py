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

Each packet is stamped with the world's (paced) clock, so the firmware's clock, which
follows the stamps (§1.5), runs with the bench's; every call tells the clock the feeder
is alive (a starved process pauses the world instead of jumping it ahead).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation

from drivers.codecs.sitl import encode_fdm_imu

__all__ = ["HexapodFdm"]


class HexapodFdm:
    """``fdm(wall_t)``: the next FDM packet of ``world`` (a ``SimImuRig`` on a paced clock)."""

    def __init__(self, world: Any) -> None:
        self.world = world
        self.clock = world.clock
        self._alive = getattr(self.clock, "alive", None)
        self.last_t = -np.inf

    def __call__(self, _wall_t: float) -> bytes:
        if self._alive is not None:
            self._alive("sitl")
        t = self.clock.now()
        t = max(t, self.last_t + 1e-6)  # the firmware drops a packet whose time goes back
        self.last_t = t
        truth, gyro, acc = self.world.imu.sample_at(np.array([t]))
        q = Rotation.from_euler("xyz", truth.euler_rad[0]).as_quat(scalar_first=True)
        (gx, gy, gz), (ax, ay, az) = gyro[0].tolist(), acc[0].tolist()
        qw, qx, qy, qz = q.tolist()
        return encode_fdm_imu(t, (gx, gy, gz), (ax, ay, az), (qw, qx, qy, qz))
