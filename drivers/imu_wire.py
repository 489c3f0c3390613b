"""The IMU bench's real serial IMUs, and their wire-level simulated peers on ptys.

Backends (``drivers.backends``), turned into the IMU bench's contracts
(``drivers.hexapod_contracts``):

* :class:`MspImuSensor`, the IMU under test: a flight controller polled over MSP
  (``MSP_RAW_IMU``, protocols.md §1.4). Betaflight and INAV send the gyro in whole deg/s;
  the accelerometer in counts, 1 g = ``acc_1g`` (Betaflight: the driver's ``acc_1G``, 2048
  for the MPU6000/6050/ICM-2060x class at ±16 g; INAV: always 512). RAW_IMU carries no
  time stamp, so a row is stamped with the host clock when its reply arrives: the FC's
  sensor/filter latency and the wire's latency become part of the hexapod-IMU time offset
  the calibration estimates, and their jitter is noise.
* :class:`Gx3Reference`, the reference IMU: a 3DM-GX3-25 streaming ``0xCF`` (Euler angles
  and rates, §2.2) in continuous mode. Rows carry the device's own timer (62 500 ticks/s,
  unwrapped); it is mapped onto the host clock by the smallest ``arrival - device time``
  seen over the last ``window_s`` (the least-delayed packets; the sliding window follows a
  crystal's drift), so the USB/pty jitter does not enter the stamps. Euler angles become
  the scalar-first quaternion of the contract with the Z-Y-X convention of the hexapod's
  poses (``Rotation.from_euler("xyz", ...)``, extrinsic x-y-z).

Simulated peers (``serial://sim/<name>``): :class:`PacedClock` runs the simulated IMU
bench (:class:`drivers.sim.imu_rig.SimImuRig`: hexapod plant, IMU model, reference) on the
wall clock, ``time_scale`` simulated seconds per wall second, so the backends' threads,
timeouts and the pty's latency act on it as on a bench. :func:`start_msp_peer` answers
MSP from the same IMU model ``sim://imu`` uses (mounting, scale, axes, lever arm, bias,
noise), sampled ``clock_offset_s`` before the request arrives (the FC's sensor latency);
:func:`start_gx3_peer` streams the platform's attitude and rates with the reference's
noise, its timer counting simulated time.
"""

from __future__ import annotations

import contextlib
import dataclasses
import math
import threading
import time
from collections import deque
from collections.abc import Iterator
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation

from drivers.codecs import gx3, msp
from drivers.contracts import Block, ChannelInfo, DeviceInfo
from drivers.errors import DeviceError
from drivers.hexapod_contracts import IMU_CHANNELS, REFERENCE_IMU_CHANNELS
from drivers.sim.clock import SimClock
from drivers.sim.imu import ImuModel, SimImu
from drivers.sim.imu_rig import SimImuRig

__all__ = ["BTFL_ACC_1G", "Gx3Reference", "HeldUploads", "MspImuSensor", "PacedClock",
           "start_gx3_peer", "start_msp_peer"]

BTFL_ACC_1G = 2048  # §1.4: Betaflight MPU6000/6050-class driver acc_1G (512 * 4), ±16 g
_MAX_BURST = 16  # GX3 packets written per wakeup of the simulated device at most
_MSP_GYRO = ("gyro_x_rad_s", "gyro_y_rad_s", "gyro_z_rad_s")
_MSP_ACC = ("acc_x_m_s2", "acc_y_m_s2", "acc_z_m_s2")


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
                 max_pause_s: float = 0.3) -> None:
        super().__init__()
        if not (math.isfinite(time_scale) and time_scale > 0):
            raise DeviceError(f"time_scale {time_scale!r}: expected a positive number")
        self.time_scale = float(time_scale)
        self.max_gap_s = float(max_gap_s)
        self._lock = threading.Lock()
        self._wall0 = self._last_wall = time.monotonic()
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

    @contextlib.contextmanager
    def hold(self) -> Iterator[None]:
        """Simulated time stands still inside the block, then goes on from where it was."""
        held = self.now_ns()
        with self._lock:
            self._held = held
        try:
            yield
        finally:
            with self._lock:
                wall = time.monotonic()
                self._wall0 = wall - held * 1e-9 / self.time_scale
                self._last_wall = wall
                self._held = None


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


# -- host side ---------------------------------------------------------------------------------
class MspImuSensor:
    """An :class:`drivers.backends.msp_fc.MspImu` as the IMU under test (``IMU_CHANNELS``)."""

    def __init__(self, imu: Any, rate_hz: float | None = None, *, port: Any = None,
                 peer: Any = None) -> None:
        self.imu = imu
        self.rate_hz = imu.rate_hz if rate_hz is None else rate_hz  # of the rig clock
        self.port, self.peer = port, peer  # closed with the sensor; the simulated FC
        self._last_t = -math.inf

    def describe(self) -> DeviceInfo:
        info = self.imu.describe()
        rate = self.rate_hz
        chans = tuple(ChannelInfo(c, "rad/s" if "gyro" in c else "m/s^2", rate)
                      for c in IMU_CHANNELS)
        return DeviceInfo("imu", info.model, info.url, chans,
                          {"time_stamps": "host clock at reply arrival (RAW_IMU has none)"})

    def read_block(self) -> Block:
        """The rows since the previous call; a row not later than the one before (two
        replies within one clock tick) is dropped, so stamps strictly increase."""
        b = self.imu.read_block()
        src = (*_MSP_GYRO, *_MSP_ACC)
        t = np.asarray(b.t_s, float)
        keep = t > np.maximum.accumulate(np.concatenate(([self._last_t], t[:-1])))
        if not keep.any():
            return Block.empty(IMU_CHANNELS)
        self._last_t = float(t[keep][-1])
        return Block(t[keep], {c: np.asarray(b.values[s], float)[keep]
                               for c, s in zip(IMU_CHANNELS, src, strict=True)})

    def close(self) -> None:
        try:
            self.imu.close()
        finally:
            if self.port is not None:
                self.port.close()


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
        for c, s in zip(REFERENCE_IMU_CHANNELS[4:], _MSP_GYRO, strict=True):
            out[c] = np.asarray(v[s], float)
        return Block(t, out)

    def close(self) -> None:
        try:
            self.dev.close()
        finally:
            if self.port is not None:
                self.port.close()


# -- simulated peers ---------------------------------------------------------------------------
class _FixedModel(ImuModel):
    """An :class:`ImuModel` whose forward matrices are computed once (one sample a call)."""

    def forward_gyro(self) -> Any:
        if "_fg" not in self.__dict__:
            self.__dict__["_fg"] = ImuModel.forward_gyro(self)
        return self.__dict__["_fg"]

    def forward_acc(self) -> Any:
        if "_fa" not in self.__dict__:
            self.__dict__["_fa"] = ImuModel.forward_acc(self)
        return self.__dict__["_fa"]


class _PlantImu:
    """The IMU under test's model on the plant, one sample at a time (thread-safe)."""

    def __init__(self, sim: SimImuRig, clock: SimClock) -> None:
        self.sim, self.clock = sim, clock
        self.lock = threading.Lock()
        self._sensor: SimImu | None = None

    def _model(self) -> SimImu:
        lever = tuple(self.sim.imu.lever_arm_from_pivot().tolist())
        if self._sensor is None or self._sensor.model.lever_arm_m != lever:
            fields = {f.name: getattr(self.sim.model, f.name)
                      for f in dataclasses.fields(self.sim.model)}
            model = _FixedModel(**{**fields, "lever_arm_m": lever})
            self._sensor = SimImu(model, self.sim.imu.rng)
        return self._sensor

    def __call__(self, _wall_t: float) -> tuple[Any, Any, Any]:
        alive = getattr(self.clock, "alive", None)
        if alive is not None:
            alive("msp")
        with self.lock:
            t = self.clock.now() - self.sim.model.clock_offset_s  # the FC's sensor latency
            truth = self.sim.hexapod.state_at(np.array([t]))
            gyro, acc = self._model().measure(truth)
        return tuple(acc[0]), tuple(gyro[0]), tuple(truth.euler_rad[0])


def start_msp_peer(sim: SimImuRig, clock: SimClock, *, variant: str = "BTFL",
                   acc_1g: int = BTFL_ACC_1G) -> Any:
    """A Betaflight- (or INAV-) like FC on a pty answering from the plant's IMU model."""
    from drivers.wire_sim.msp_fc import SimFlightController

    class PlantFc(SimFlightController):
        def _reply(self, m: msp.MspMessage) -> bytes:
            if isinstance(m, msp.Request) and m.cmd == msp.MSP_FC_VARIANT:
                return msp.encode_message(msp.FcVariant(variant))
            return super()._reply(m)

    return PlantFc(_PlantImu(sim, clock), acc_1g=acc_1g).start()


def start_gx3_peer(sim: SimImuRig, clock: SimClock) -> Any:
    """A 3DM-GX3-25 on a pty; its timer and its stream run on the plant's clock."""
    from drivers.wire_sim.gx3 import SimGx3

    ref = sim.reference_imu
    period = 1.0 / ref.rate_hz
    alive = getattr(clock, "alive", None)
    lock = threading.Lock()

    def sample(t: float) -> tuple[Any, Any, Any]:
        with lock:
            s = sim.hexapod.state_at(np.array([t]))
            att = Rotation.from_euler("xyz", s.euler_rad) * Rotation.from_rotvec(
                ref.rng.normal(0.0, ref.attitude_noise_rad, (1, 3)))
            rate = s.omega_b_rad_s[0] + ref.rng.normal(0.0, ref.gyro_noise_rad_s, 3)
        return (0.0, 0.0, 0.0), tuple(rate), tuple(att.as_euler("xyz")[0])

    class PlantGx3(SimGx3):
        def _packet(self, cmd: int, t: float | None = None) -> bytes:
            """The packet of the sample taken at ``t`` (default now), timer included."""
            t = clock.now() if t is None else t
            ticks = round(t * gx3.TICKS_PER_SECOND) & 0xFFFFFFFF
            if cmd != gx3.EULER_RATES:
                return super()._packet(cmd)
            _, rate, euler = sample(t)
            return gx3.encode_reply(gx3.EulerRates(ticks, *euler, rate))

        def handle(self, data: bytes) -> bytes:
            seen = len(self.requests)
            out = super().handle(data)
            if any(r[0] == gx3.SET_CONTINUOUS for r in self.requests[seen:]):
                self._next = clock.now()  # the stream starts now, on the plant clock
            return out

        def tick(self) -> bytes:
            """Every packet due on the plant clock (a late wakeup sends the backlog)."""
            if self.stream_cmd is None:
                return b""
            if alive is not None:
                alive("gx3")
            out = bytearray()
            for _ in range(_MAX_BURST):  # a starved thread writes what it has, then goes on
                if self.stream_cmd is None or clock.now() < self._next:
                    break
                out += self._packet(self.stream_cmd, self._next)  # on the device's grid
                self._next += self.period_s
            return bytes(out)

    peer = PlantGx3(lambda t: sample(clock.now()), period_s=period)
    # wake every 2 ms of wall time at most (fewer wakeups: less GIL traffic for the host)
    peer.port.tick_s = min(0.002, period / getattr(clock, "time_scale", 1.0) / 2)
    return peer.start()
