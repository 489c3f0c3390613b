"""A simulated 3DM-GX3-25 (single-byte protocol) on a pseudo-terminal.

Answers polled data packets, ``C4 C1 29 <cmd>`` (ack, then the packet streamed every
``period_s``), ``FA 75 B4`` (stop, no reply), ``FE 9E 3A`` (reset, no reply) — protocols.md
§2.2. The data come from ``imu(t_s) -> (acc_m_s2, rate_rad_s, (roll, pitch, yaw))`` and
the device timer counts 62 500 ticks per second from the start.
"""

from __future__ import annotations

import time
from collections.abc import Callable

from drivers.codecs import gx3
from drivers.wire_sim.pty_port import PtyDevice
from drivers.wire_sim.pty_sim import PtySimulator

Vec3 = tuple[float, float, float]
ImuModel = Callable[[float], tuple[Vec3, Vec3, Vec3]]

# host request lengths (§2.2): command byte + confirm bytes + arguments
_REQUEST_LENGTH = {gx3.SET_CONTINUOUS: 4, gx3.STOP_CONTINUOUS: 3, gx3.DEVICE_RESET: 3,
                   gx3.CAPTURE_GYRO_BIAS: 5, gx3.DEVICE_ID: 2}


class SimGx3(PtySimulator):
    """Simulated IMU; ``stream_cmd`` is the packet in continuous mode (or None)."""

    def __init__(self, imu: ImuModel, *, period_s: float = 0.01) -> None:
        self.imu = imu
        self.period_s = period_s  # 100 Hz: the reference's default continuous rate [U]
        self.stream_cmd: int | None = None
        self.requests: list[bytes] = []
        self._buf = bytearray()
        self._t0 = time.monotonic()
        self._next = 0.0
        self.port = PtyDevice(self.handle, tick=self.tick, tick_s=period_s / 4)

    def _packet(self, cmd: int) -> bytes:
        t = time.monotonic() - self._t0
        acc, rate, euler = self.imu(t)
        ticks = int(t * gx3.TICKS_PER_SECOND) & 0xFFFFFFFF
        msg: gx3.Gx3Message
        if cmd == gx3.ACCEL_RATE:
            msg = gx3.AccelRate(ticks, acc, rate)
        elif cmd == gx3.EULER:
            msg = gx3.Euler(ticks, *euler)
        elif cmd == gx3.EULER_RATES:
            msg = gx3.EulerRates(ticks, *euler, rate)
        elif cmd == gx3.ACCEL_RATE_MAG:
            msg = gx3.AccelRateMag(ticks, cmd, acc, rate, (0.0, 0.0, 0.0))
        else:
            body = bytes(gx3.REPLY_LENGTH[cmd] - 3)
            msg = gx3.Reply(cmd, body.hex())
        return gx3.encode_reply(msg)

    def handle(self, data: bytes) -> bytes:
        self._buf += data
        out = bytearray()
        while self._buf:
            cmd = self._buf[0]
            n = _REQUEST_LENGTH.get(cmd, 1)
            if len(self._buf) < n:
                break
            req = bytes(self._buf[:n])
            del self._buf[:n]
            self.requests.append(req)
            if cmd == gx3.SET_CONTINUOUS and req[1:3] == b"\xC1\x29":
                self.stream_cmd = req[3]
                self._next = time.monotonic()
                ticks = int((time.monotonic() - self._t0) * gx3.TICKS_PER_SECOND) & 0xFFFFFFFF
                out += gx3.encode_reply(gx3.ContinuousAck(ticks, req[3]))
            elif cmd == gx3.STOP_CONTINUOUS and req == gx3.stop_continuous():
                self.stream_cmd = None
            elif cmd in gx3.REPLY_LENGTH and n == 1:
                out += self._packet(cmd)
        return bytes(out)

    def tick(self) -> bytes:
        if self.stream_cmd is None or time.monotonic() < self._next:
            return b""
        self._next += self.period_s
        return self._packet(self.stream_cmd)
