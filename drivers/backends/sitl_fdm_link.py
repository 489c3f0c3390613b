"""The simulator's end of the Betaflight SITL's UDP interface: FDM out, motor outputs in.

One ``fdm_packet`` to UDP 9003 per plant tick, and the firmware's answer, one
``servo_packet_raw`` on UDP 9001 (motor outputs in microseconds, Betaflight's motor order),
computed in its first PID iteration after that packet (betaflight-sitl reference §1.4:
nothing is sent while FDM is silent). :meth:`FdmLink.exchange` sends and then waits, at
most until the caller's deadline (the next tick), for that answer: request and response
in step while the firmware keeps up, the last outputs held when it does not.

Stamps come from ``drivers.codecs.sitl.fdm_stamps`` (steady 25 ms steps): the firmware
re-estimates its clock rate for stamps under 20 ms apart, so its clock stays the host's
monotonic clock and the plant must run in wall-clock time.
"""

from __future__ import annotations

import contextlib
import select
import socket
import time

from drivers.codecs.msp import Quat
from drivers.codecs.sitl import (
    FDM_PORT,
    MOTOR_RAW_PORT,
    MOTOR_RAW_SIZE,
    MotorOutputs,
    decode_motor_raw,
    encode_fdm_imu,
    fdm_stamps,
)
from drivers.errors import DeviceError

__all__ = ["FdmLink", "motor_listener"]

Vec3 = tuple[float, float, float]


def motor_listener(host: str) -> socket.socket:
    """A non-blocking UDP socket bound to the SITL's motor-output port on ``host``."""
    rx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        rx.bind((host, MOTOR_RAW_PORT))
    except OSError as exc:
        rx.close()
        raise DeviceError(f"cannot listen for the SITL's motor outputs on UDP "
                          f"{host}:{MOTOR_RAW_PORT} ({exc.strerror or exc})") from None
    rx.setblocking(False)
    return rx


class FdmLink:
    """UDP to and from one SITL at ``host`` (its network namespace's loopback)."""

    def __init__(self, host: str = "127.0.0.1") -> None:
        self.host = host
        self.stamps = fdm_stamps()
        self.rx = motor_listener(host)
        self.tx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sent = 0
        self.answered = 0  # FDM packets answered before the caller's deadline

    def exchange(self, gyro_flu: Vec3, specific_force_flu: Vec3, body_to_enu: Quat,
                 deadline: float) -> MotorOutputs | None:
        """Send one FDM packet (forward-left-up body, east-north-up earth: the codec turns
        them into the packet's FRD/NED frames) and return the firmware's answer, or None
        when none came by ``deadline`` (``time.monotonic``): then the newest late answer to
        an earlier packet, if any."""
        late = self._read()  # answers to earlier packets that came after their deadline
        packet = encode_fdm_imu(next(self.stamps), gyro_flu, specific_force_flu, body_to_enu)
        self.tx.sendto(packet, (self.host, FDM_PORT))
        self.sent += 1
        while True:
            fresh = self._read()
            if fresh is not None:
                self.answered += 1
                return fresh
            left = deadline - time.monotonic()
            if left <= 0 or not select.select([self.rx], [], [], left)[0]:
                return late

    def _read(self) -> MotorOutputs | None:
        """The newest motor packet waiting, or None."""
        last = None
        while True:
            try:
                data = self.rx.recv(256)
            except BlockingIOError:
                return last
            if len(data) == MOTOR_RAW_SIZE:
                last = decode_motor_raw(data)

    def close(self) -> None:
        for s in (self.tx, self.rx):
            with contextlib.suppress(OSError):
                s.close()
