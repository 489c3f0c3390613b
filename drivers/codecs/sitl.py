"""Betaflight 4.6.0 SITL's UDP packets: the FDM packet it reads, the motor packet it sends.

Native little-endian C structs, accepted only at their exact size (the firmware drops any
other length silently, so a wrong size here is an error, not a truncation):

* ``fdm_packet`` (host -> UDP 9003, ``<18d``, 144 B): time stamp [s], body rates
  (FRD, rad/s), the accelerometer's input (minus the specific force in forward-left-up
  axes, m/s^2), the FRD-body -> NED quaternion (w, x, y, z), velocity, position and
  pressure [Pa]. The firmware is built with fast-math: NaN or Inf are refused here.
* ``servo_packet_raw`` (firmware -> UDP 9001, ``<H2x16f``, 68 B): the motor count, then
  the motor outputs in microseconds in Betaflight's motor order (motors first, then
  servos). Unlike ``servo_packet`` on 9002 it needs no re-ordering or rescaling, and the
  firmware sends it only with a fresh motor update (not for the stale re-sync reply).

The FDM time stamp sets only the firmware's clock rate (sitl.c ``updateState``): for a
step under 20 ms it becomes the step over the wall time between this packet's receipt and
the last one's, applied until the next packet. Under host load packets queue and are read
in a burst, so one such ratio can be hundreds, and the firmware's clock (``millis()``)
then leaps by seconds: an armed FC's receiver failsafe tripped with the bench's RC frames
never more than 0.2 s apart. :func:`fdm_stamps` steps 25 ms per packet, so the rate is
never re-estimated and the firmware's clock stays the host's monotonic clock.
"""

from __future__ import annotations

import itertools
import math
import struct
from collections.abc import Iterator
from dataclasses import dataclass

from drivers.codecs.msp import FRD_FROM_FLU, NED_FROM_ENU, Quat, quat_mul

__all__ = ["ACC_COUNTS_PER_M_S2", "FDM_PORT", "FDM_SIZE", "GYRO_COUNTS_PER_RAD_S",
           "MOTOR_RAW_PORT", "MOTOR_RAW_SIZE", "MSP_PORT", "RC_PORT", "SITL_ACC_1G",
           "SITL_GYRO_LSB_PER_DPS", "STANDARD_GRAVITY", "STANDARD_PRESSURE_PA",
           "MotorOutputs", "decode_motor_raw", "encode_fdm", "encode_fdm_at_rest",
           "encode_fdm_imu", "fdm_stamps", "whole_counts"]

MSP_PORT = 5761  # UART1 (MSP) on TCP 5760 + 1
FDM_PORT = 9003
RC_PORT = 9004
MOTOR_RAW_PORT = 9001
STANDARD_GRAVITY = 9.80665
STANDARD_PRESSURE_PA = 101325.0
FDM_STAMP_STEP_S = 0.025  # >= 20 ms: the firmware keeps its clock rate at 1 (module doc)
#: the virtual sensors' scales (sitl.c): counts per deg/s and per g (acc_1G)
SITL_GYRO_LSB_PER_DPS = 16.4
SITL_ACC_1G = 256
GYRO_COUNTS_PER_RAD_S = SITL_GYRO_LSB_PER_DPS * 180.0 / math.pi
ACC_COUNTS_PER_M_S2 = SITL_ACC_1G / STANDARD_GRAVITY

_FDM = struct.Struct("<18d")
_RAW = struct.Struct("<H2x16f")
FDM_SIZE = _FDM.size  # 144
MOTOR_RAW_SIZE = _RAW.size  # 68

Vec3 = tuple[float, float, float]


@dataclass(frozen=True)
class MotorOutputs:
    """One motor update of the firmware: ``motor_us[i]`` is Betaflight motor i+1."""

    motor_us: tuple[float, ...]


def encode_fdm(t_s: float, gyro_frd_rad_s: Vec3, acc_input_m_s2: Vec3,
               quat_wxyz: tuple[float, float, float, float] = (1.0, 0.0, 0.0, 0.0),
               velocity: Vec3 = (0.0, 0.0, 0.0), position: Vec3 = (0.0, 0.0, 0.0),
               pressure_pa: float = STANDARD_PRESSURE_PA) -> bytes:
    """One ``fdm_packet``; ``acc_input_m_s2`` is what the packet carries (minus the
    specific force in FLU axes: level at rest is (0, 0, -g))."""
    values = (t_s, *gyro_frd_rad_s, *acc_input_m_s2, *quat_wxyz, *velocity, *position,
              pressure_pa)
    if len(values) != 18:
        raise ValueError(f"fdm_packet: expected 18 values, got {len(values)}")
    if not all(math.isfinite(v) for v in values):
        raise ValueError("fdm_packet: NaN or Inf (the fast-math firmware cannot take them)")
    return _FDM.pack(*values)


def encode_fdm_at_rest(t_s: float) -> bytes:
    """A level flight controller at rest: no rotation, gravity only, standard pressure."""
    return encode_fdm(t_s, (0.0, 0.0, 0.0), (0.0, 0.0, -STANDARD_GRAVITY))


def fdm_stamps() -> Iterator[float]:
    """The time stamps of one firmware's FDM packets, in order (one feeder per firmware):
    ``FDM_STAMP_STEP_S`` apart whatever the send rate, so its clock runs at real time."""
    return (n * FDM_STAMP_STEP_S for n in itertools.count(1))


def decode_motor_raw(data: bytes) -> MotorOutputs:
    """A ``servo_packet_raw``: the ``motorCount`` motor outputs in microseconds."""
    if len(data) != MOTOR_RAW_SIZE:
        raise ValueError(f"servo_packet_raw: expected {MOTOR_RAW_SIZE} bytes, got {len(data)}")
    count, *values = _RAW.unpack(data)
    if count > len(values):
        raise ValueError(f"servo_packet_raw: motor count {count} > {len(values)}")
    return MotorOutputs(tuple(float(v) for v in values[:count]))


def whole_counts(value: float, counts_per_unit: float) -> float:
    """The packet value the firmware turns into ``round(value * counts_per_unit)`` counts.

    The SITL converts a packet's double to its int16 sensor counts by truncation toward
    zero (sitl.c), a dead band of one count around zero: a sine of amplitude A counts
    reads 2/(pi A) small in scale (0.24 % for the 4 deg gyro sines of Paper A). A
    sensor's converter rounds; so the bench hands over whole counts with half a count
    away from zero, which truncation brings back to exactly those counts."""
    n = round(value * counts_per_unit)
    return (n + math.copysign(0.5, n)) / counts_per_unit if n else 0.0


def encode_fdm_imu(t_s: float, gyro_flu_rad_s: Vec3, specific_force_flu_m_s2: Vec3,
                   body_to_enu: Quat) -> bytes:
    """An ``fdm_packet`` from what an IMU in Betaflight's forward-left-up body axes
    measures (rate, specific force: level at rest (0, 0, +g)) and the body's attitude
    (forward-left-up body -> east-north-up earth), in the packet's frames: body rates in
    FRD, minus the specific force in FLU (sitl.c negates it), FRD -> NED attitude, each
    reading as the whole counts of the firmware's own scales (:func:`whole_counts`)."""
    gx, gy, gz = (whole_counts(w, GYRO_COUNTS_PER_RAD_S) for w in gyro_flu_rad_s)
    fx, fy, fz = (whole_counts(f, ACC_COUNTS_PER_M_S2) for f in specific_force_flu_m_s2)
    quat = quat_mul(quat_mul(NED_FROM_ENU, body_to_enu), FRD_FROM_FLU)
    return encode_fdm(t_s, (gx, -gy, -gz), (-fx, -fy, -fz), quat)
