"""MicroStrain 3DM-GX3-25 reference IMU over serial, in continuous mode (``Sensor``).

Open: stop any running stream (``FA 75 B4``), drop stale input, ask for continuous
``packet`` replies (``C4 C1 29 <cmd>``) and wait for the 8-byte ack that echoes the
command (protocols.md §2.2, as the ROS driver checks). A reader thread then decodes the
stream; each packet becomes one row. ``t_s`` is the rig clock at reception; the device's
own timer (62 500 ticks/s, unwrapped) is kept as ``device_t_s`` for precise spacing.
``close()`` stops the stream.

:class:`Gx3Reference` is a GX3 streaming ``0xCF`` (Euler angles and rates, §2.2) as the
IMU bench's reference IMU. Rows carry the device's own timer; it is mapped onto the host
clock by the smallest ``arrival - device time`` seen over the last ``window_s`` (the
least-delayed packets; the sliding window follows a crystal's drift), so the USB/pty
jitter does not enter the stamps. Euler angles become the scalar-first quaternion of the
contract with the Z-Y-X convention of the hexapod's poses (``Rotation.from_euler("xyz",
...)``, extrinsic x-y-z).
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import fields
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation

from drivers.backends.row_stream import SerialStreamSensor
from drivers.backends.serial_link import Deadline, read_some, write_all
from drivers.codecs import gx3
from drivers.contracts import REFERENCE_IMU_CHANNELS, Block, ChannelInfo, Clock, DeviceInfo
from drivers.errors import DeviceError

# message field -> column names (SI units in the names)
_COLUMNS = {
    "acc_m_s2": ("acc_x_m_s2", "acc_y_m_s2", "acc_z_m_s2"),
    "rate_rad_s": ("gyro_x_rad_s", "gyro_y_rad_s", "gyro_z_rad_s"),
    "mag_gauss": ("mag_x_gauss", "mag_y_gauss", "mag_z_gauss"),
    "roll_rad": ("roll_rad",),
    "pitch_rad": ("pitch_rad",),
    "yaw_rad": ("yaw_rad",),
}
PACKETS = {gx3.ACCEL_RATE: gx3.AccelRate, gx3.ACCEL_RATE_MAG: gx3.AccelRateMag,
           gx3.EULER: gx3.Euler, gx3.EULER_RATES: gx3.EulerRates}


def columns_for(packet: int) -> tuple[str, ...]:
    cls = PACKETS[packet]
    return tuple(c for f in fields(cls) if f.name in _COLUMNS for c in _COLUMNS[f.name])


class Gx3Imu(SerialStreamSensor):
    """The reference IMU streaming ``packet`` (default 0xC2 acceleration & rate)."""

    def __init__(self, port: Any, *, packet: int = gx3.ACCEL_RATE, clock: Clock | None = None,
                 stale_s: float = 0.2, open_timeout_s: float = 1.0,
                 url: str = "serial://gx3") -> None:
        if packet not in PACKETS:
            raise DeviceError(f"{url}: packet 0x{packet:02X} not supported "
                              f"(use one of {[hex(p) for p in PACKETS]})")
        super().__init__(port, clock=clock, stale_s=stale_s, url=url)
        self.packet = packet
        self.columns = columns_for(packet)
        self.names = (*self.columns, "device_t_s")
        self.decoder = gx3.Gx3Decoder()
        self._unwrap = gx3.TimerUnwrapper()
        self._start_stream(open_timeout_s)
        self._start_reader(f"gx3-{url}")

    def _start_stream(self, timeout_s: float) -> None:
        write_all(self.port, gx3.stop_continuous(), self.url)
        self.port.reset_input_buffer()
        write_all(self.port, gx3.set_continuous(self.packet), self.url)
        deadline = Deadline(timeout_s)
        while not deadline.expired:
            for m in self.decoder.feed(read_some(self.port, self.url)):
                if isinstance(m, gx3.ContinuousAck) and m.cmd == self.packet:
                    return
        raise DeviceError(f"{self.url}: no continuous-mode ack (C4 .. {self.packet:02X}) within "
                          f"{timeout_s} s; is it a 3DM-GX3 with single-byte firmware (< 2.0)?")

    def describe(self) -> DeviceInfo:
        unit = {"m_s2": "m/s^2", "rad_s": "rad/s", "gauss": "gauss", "rad": "rad"}
        chans = tuple(ChannelInfo(c, next(u for k, u in unit.items() if c.endswith(k)), 0.0)
                      for c in self.columns)
        return DeviceInfo(kind="imu", model="MicroStrain 3DM-GX3-25", url=self.url,
                          channels=(*chans, ChannelInfo("device_t_s", "s", 0.0)),
                          extra={"packet": f"0x{self.packet:02X}", "stats": self.decoder.stats})

    def _row(self, m: Any, now: float) -> tuple[float, ...]:
        vals: list[float] = []
        for f in fields(m):
            if f.name in _COLUMNS:
                v = getattr(m, f.name)
                vals.extend(v if isinstance(v, tuple) else (v,))
        return (now, *vals, self._unwrap.seconds(m.timer_ticks))

    def _decode(self, data: bytes, now: float) -> list[tuple[float, ...]]:
        cls = PACKETS[self.packet]
        return [self._row(m, now) for m in self.decoder.feed(data) if isinstance(m, cls)]

    def _silence(self, silent_s: float) -> str:
        return f"{self.url}: no packet for {silent_s:.3f} s (disconnected?)"

    def close(self) -> None:
        super().close()
        try:
            write_all(self.port, gx3.stop_continuous(), self.url)
        except DeviceError:
            pass


_GYRO = ("gyro_x_rad_s", "gyro_y_rad_s", "gyro_z_rad_s")


class Gx3Reference:
    """A :class:`drivers.backends.gx3_imu.Gx3Imu` streaming 0xCF as the reference IMU
    (``REFERENCE_IMU_CHANNELS``), stamped from the device timer (see module doc)."""

    def __init__(self, gx3_imu: Any, *, window_s: float = 5.0, port: Any = None,
                 peer: Any = None) -> None:
        if gx3_imu.packet != gx3.EULER_RATES:
            raise DeviceError(f"{gx3_imu.url}: the reference IMU needs packet 0xCF "
                              "(Euler angles and rates)")
        self.dev = gx3_imu
        self.port, self.peer = port, peer  # closed with the sensor; the simulated GX3
        self.window_s = float(window_s)
        self._offsets: deque[tuple[float, float]] = deque()  # (arrival, min offset)
        self._last_t = -math.inf

    def link_errors(self) -> dict[str, int]:
        return self.dev.link_errors()

    def describe(self) -> DeviceInfo:
        info = self.dev.describe()
        chans = tuple(ChannelInfo(c, "1" if c.startswith("ref_q") else "rad/s", 0.0)
                      for c in REFERENCE_IMU_CHANNELS)
        return DeviceInfo("reference_imu", info.model, info.url, chans,
                          {**info.extra, "quaternion": "scalar-first, Z-Y-X Euler of 0xCF",
                           "time_stamps": "device timer + min(arrival - device) offset"})

    def host_times(self, arrival: np.ndarray, device: np.ndarray) -> np.ndarray:
        """Device times on the host clock; never running backwards."""
        now = float(arrival[-1])
        self._offsets.append((now, float(np.min(arrival - device))))
        while self._offsets[0][0] < now - self.window_s:
            self._offsets.popleft()
        offset = min(o for _, o in self._offsets)
        t = np.maximum.accumulate(np.maximum(device + offset, self._last_t))
        self._last_t = float(t[-1])
        return t

    def read_block(self) -> Block:
        b = self.dev.read_block()
        if len(b) == 0:
            return Block.empty(REFERENCE_IMU_CHANNELS)
        v = b.values
        euler = np.column_stack([v["roll_rad"], v["pitch_rad"], v["yaw_rad"]])
        q = Rotation.from_euler("xyz", euler).as_quat(canonical=True, scalar_first=True)
        t = self.host_times(np.asarray(b.t_s, float), np.asarray(v["device_t_s"], float))
        out = {c: q[:, i] for i, c in enumerate(REFERENCE_IMU_CHANNELS[:4])}
        for c, s in zip(REFERENCE_IMU_CHANNELS[4:], _GYRO, strict=True):
            out[c] = np.asarray(v[s], float)
        return Block(t, out)

    def close(self) -> None:
        try:
            self.dev.close()
        finally:
            if self.port is not None:
                self.port.close()
