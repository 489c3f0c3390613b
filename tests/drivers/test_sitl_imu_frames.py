"""The FDM packet the IMU bench sends Betaflight's SITL, read back as the firmware reads it
(sitl.c: int16 counts by truncation toward zero, gyro (p, -q, -r) x 16.4 x 180/pi, acc
-packet x 256/g; attitude echoed as roll, -pitch, yaw of the packet's quaternion), and the
MSP_ATTITUDE it then reports turned back into the bench's convention."""

from __future__ import annotations

import math
import struct

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from drivers.codecs import msp
from drivers.codecs.sitl import (
    ACC_COUNTS_PER_M_S2,
    GYRO_COUNTS_PER_RAD_S,
    encode_fdm_imu,
    whole_counts,
)

RNG = np.random.default_rng(7)


def _firmware_counts(packet: bytes) -> tuple[list[int], list[int], tuple[float, ...]]:
    """What the SITL makes of a packet: acc and gyro int16 counts (FLU), the quaternion."""
    v = struct.unpack("<18d", packet)
    acc = [math.trunc(-a * ACC_COUNTS_PER_M_S2) for a in v[4:7]]
    p, q, r = v[1:4]
    gyro = [math.trunc(w * GYRO_COUNTS_PER_RAD_S) for w in (p, -q, -r)]
    return acc, gyro, v[7:11]


def test_the_firmware_reads_the_rounded_counts_of_the_flu_readings() -> None:
    for _ in range(200):
        gyro = tuple(RNG.uniform(-3.0, 3.0, 3).tolist())
        force = tuple(RNG.uniform(-30.0, 30.0, 3).tolist())
        acc, rates, _ = _firmware_counts(encode_fdm_imu(1.0, gyro, force, (1.0, 0, 0, 0)))
        assert acc == [round(f * ACC_COUNTS_PER_M_S2) for f in force]
        assert rates == [round(w * GYRO_COUNTS_PER_RAD_S) for w in gyro]


def test_truncation_alone_would_shrink_a_sine() -> None:
    """Why whole counts: the firmware's truncation toward zero reads a 4 deg, 0.65 Hz gyro
    sine (about 270 counts) 2/(pi A) small; the counts the bench hands over do not."""
    t = np.linspace(0.0, 20.0, 20_001)
    w = math.radians(4.0) * 2 * math.pi * 0.65 * np.sin(2 * math.pi * 0.65 * t) + 1e-7
    amp = float(np.abs(w).max() * GYRO_COUNTS_PER_RAD_S)

    def gain(sent: np.ndarray) -> float:
        counts = np.trunc(sent * GYRO_COUNTS_PER_RAD_S)
        return float(counts @ w / (w @ w) / GYRO_COUNTS_PER_RAD_S)

    plain = gain(w)
    whole = gain(np.array([whole_counts(x, GYRO_COUNTS_PER_RAD_S) for x in w]))
    assert 1.0 - plain == pytest.approx(2 / (math.pi * amp), rel=0.2)
    assert abs(1.0 - whole) < 0.1 * (1.0 - plain)


def test_msp_attitude_of_the_echoed_quaternion_is_the_body_attitude() -> None:
    for rpy in RNG.uniform([-0.5, -0.5, -math.pi], [0.5, 0.5, math.pi], (50, 3)):
        body = Rotation.from_euler("xyz", rpy)  # FLU body -> ENU, Z-Y-X as the hexapod
        q_enu = body.as_quat(scalar_first=True)
        _, _, q_fdm = _firmware_counts(encode_fdm_imu(1.0, (0, 0, 0), (0, 0, 9.8),
                                                      tuple(q_enu.tolist())))
        # betaflight-sitl.md §1.3: roll = phi, pitch = -theta, yaw = psi of the packet's q
        yaw, pitch, roll = Rotation.from_quat(q_fdm, scalar_first=True).as_euler("ZYX")
        back = msp.attitude_quat_enu(msp.Attitude(roll, -pitch, yaw % (2 * math.pi)))
        err = (body.inv() * Rotation.from_quat(back, scalar_first=True)).magnitude()
        assert err < 1e-9
    # and the angle a pilot reads: nose down is Betaflight's positive pitch
    nose_down = Rotation.from_euler("y", 0.2).as_quat(scalar_first=True)  # about +y (left)
    _, _, q = _firmware_counts(encode_fdm_imu(0.0, (0, 0, 0), (0, 0, 9.8),
                                              tuple(nose_down.tolist())))
    _, pitch, _ = Rotation.from_quat(q, scalar_first=True).as_euler("ZYX")
    assert -pitch == pytest.approx(0.2)  # Betaflight's pitch: nose down +
