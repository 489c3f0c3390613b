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

__all__ = ["FDM_PORT", "FDM_SIZE", "MOTOR_RAW_PORT", "MOTOR_RAW_SIZE", "MSP_PORT",
           "RC_PORT", "STANDARD_GRAVITY", "STANDARD_PRESSURE_PA", "MotorOutputs",
           "decode_motor_raw", "encode_fdm", "encode_fdm_at_rest", "fdm_stamps"]

MSP_PORT = 5761  # UART1 (MSP) on TCP 5760 + 1
FDM_PORT = 9003
RC_PORT = 9004
MOTOR_RAW_PORT = 9001
STANDARD_GRAVITY = 9.80665
STANDARD_PRESSURE_PA = 101325.0
FDM_STAMP_STEP_S = 0.025  # >= 20 ms: the firmware keeps its clock rate at 1 (module doc)

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
