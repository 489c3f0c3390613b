"""Simulated IMU under test and reference IMU on the simulated hexapod (``sim://imu``,
``sim://reference-imu``).

Both sample the platform's truth (:meth:`SimHexapodDevice.state_at`) on their own clock.
The IMU under test is :class:`drivers.sim.imu.SimImu` (mounting rotation, non-orthogonal
axes, scale errors, lever arm, biases, noise, range, quantisation) behind the Sensor
contract: the sample it takes at rig time ``τ`` is stamped ``τ + clock_offset_s``, so its
stamps lag the hexapod's clock by the offset the calibration has to find. The lever arm
is measured from the centre of gravity; the hexapod reports the motion of its pivot, so
the IMU sits at ``lever_arm_m + cg_m − pivot`` from the point the reference describes.

The reference IMU (a 3DM-GX3-25 class AHRS) gives the attitude quaternion, scalar-first,
body→navigation with z up, and the body rates, with white noise.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Unpack

import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from drivers.contracts import (
    IMU_CHANNELS,
    REFERENCE_IMU_CHANNELS,
    Block,
    ChannelInfo,
    DeviceInfo,
    Fault,
)
from drivers.errors import DeviceError
from drivers.hexapod_kinematics import HexapodState
from drivers.sim.clock import SimClock
from drivers.sim.faults import FaultOptions, FaultSwitches
from drivers.sim.hexapod_device import SimHexapodDevice
from drivers.sim.imu import ImuModel, SimImu

__all__ = ["SimImuDevice", "SimReferenceImu"]

Array = NDArray[np.float64]


class _Sampler:
    """Sample instants ``k / rate`` on a device clock that reads rig time + offset."""

    def __init__(self, clock: SimClock, rate_hz: float, offset_s: float) -> None:
        self.clock, self.rate_hz, self.offset_s = clock, float(rate_hz), float(offset_s)
        self.next_k = math.floor((clock.now() + offset_s) * rate_hz) + 1

    def due(self) -> Array:
        """Device stamps of the samples taken since the previous call."""
        k_end = math.floor((self.clock.now() + self.offset_s) * self.rate_hz + 1e-9)
        if k_end < self.next_k:
            return np.empty(0)
        stamps = np.arange(self.next_k, k_end + 1) / self.rate_hz
        self.next_k = k_end + 1
        return stamps


class _CachedModel(ImuModel):
    """An :class:`ImuModel` whose forward matrices are computed once (read on every block)."""

    def forward_gyro(self) -> Array:
        if "_fg" not in self.__dict__:
            self.__dict__["_fg"] = ImuModel.forward_gyro(self)
        return self.__dict__["_fg"]

    def forward_acc(self) -> Array:
        if "_fa" not in self.__dict__:
            self.__dict__["_fa"] = ImuModel.forward_acc(self)
        return self.__dict__["_fa"]


class SimImuDevice:
    """The IMU under test as a Sensor (columns ``IMU_CHANNELS``, stamps on its own clock)."""

    def __init__(self, clock: SimClock, hexapod: SimHexapodDevice, model: ImuModel,
                 rng: np.random.Generator, *, cg_m: tuple[float, float, float] = (0.0, 0.0, 0.0),
                 url: str = "sim://imu") -> None:
        self.clock, self.hexapod, self.model, self.url = clock, hexapod, model, url
        self.cg_m = np.asarray(cg_m, dtype=float)
        self.rng = rng
        self._sampler = _Sampler(clock, model.rate_hz, model.clock_offset_s)
        self.faults = FaultSwitches("sim imu", np.random.default_rng(rng.integers(2**63)),
                                    tuple(Fault))
        self._sim: SimImu | None = None
        self.closed = False

    def describe(self) -> DeviceInfo:
        m = self.model
        chans = tuple(
            ChannelInfo(c, "rad/s", m.rate_hz, -m.gyro_range_rad_s, m.gyro_range_rad_s)
            if "gyro" in c else
            ChannelInfo(c, "m/s^2", m.rate_hz, -m.acc_range_m_s2, m.acc_range_m_s2)
            for c in IMU_CHANNELS)
        return DeviceInfo("imu", "simulated IMU (ADIS16400 class)", self.url, chans,
                          {"rate_hz": m.rate_hz, "clock": "own (offset from the hexapod)"})

    def _imu(self) -> SimImu:
        """The sensor model with the lever arm seen from the present pivot."""
        lever = tuple(self.lever_arm_from_pivot().tolist())
        if self._sim is None or self._sim.model.lever_arm_m != lever:
            fields = {f.name: getattr(self.model, f.name)
                      for f in dataclasses.fields(self.model)}
            self._sim = SimImu(_CachedModel(**{**fields, "lever_arm_m": lever}), self.rng)
        return self._sim

    def lever_arm_from_pivot(self) -> Array:
        return np.asarray(self.model.lever_arm_m) + self.cg_m - np.asarray(self.hexapod.pivot_m)

    def sample_at(self, stamps: Array) -> tuple[HexapodState, Array, Array]:
        """The truth and the model's gyro and accelerometer readings of samples stamped
        ``stamps`` (taken ``clock_offset_s`` earlier): one home for the sensor model, read
        here and by whatever else the model feeds (the Betaflight SITL's FDM input)."""
        truth = self.hexapod.state_at(np.asarray(stamps, float) - self.model.clock_offset_s)
        gyro, acc = self._imu().measure(truth)
        return truth, gyro, acc

    def read_block(self) -> Block:
        if self.closed:
            raise DeviceError("sim imu: read after close")
        now = self.clock.now()
        self.faults.check(now, "read_block")
        stamps = self._sampler.due()
        if stamps.size == 0:
            return Block.empty(IMU_CHANNELS)
        _, gyro, acc = self.sample_at(stamps)
        data = np.hstack([gyro, acc])
        block = Block(stamps, {c: data[:, i] for i, c in enumerate(IMU_CHANNELS)})
        full = {c: (self.model.gyro_range_rad_s if "gyro" in c else self.model.acc_range_m_s2)
                for c in IMU_CHANNELS}
        return self.faults.apply(block, full)

    def inject(self, fault: Fault | str, **kwargs: Unpack[FaultOptions]) -> None:
        self.faults.inject(fault, **kwargs)

    def close(self) -> None:
        self.closed = True


class SimReferenceImu:
    """Reference AHRS on the platform: quaternion ``[w, x, y, z]`` and body rates."""

    def __init__(self, clock: SimClock, hexapod: SimHexapodDevice, rng: np.random.Generator, *,
                 rate_hz: float = 100.0, attitude_noise_rad: float = math.radians(0.1),
                 gyro_noise_rad_s: float = 0.002, url: str = "sim://reference-imu") -> None:
        self.clock, self.hexapod, self.rng, self.url = clock, hexapod, rng, url
        self.rate_hz = float(rate_hz)
        self.attitude_noise_rad = float(attitude_noise_rad)
        self.gyro_noise_rad_s = float(gyro_noise_rad_s)
        self._sampler = _Sampler(clock, rate_hz, 0.0)
        self.faults = FaultSwitches("sim reference imu",
                                    np.random.default_rng(rng.integers(2**63)), tuple(Fault))
        self.closed = False

    def describe(self) -> DeviceInfo:
        chans = tuple(ChannelInfo(c, "1" if c.startswith("ref_q") else "rad/s", self.rate_hz)
                      for c in REFERENCE_IMU_CHANNELS)
        return DeviceInfo("reference_imu", "simulated AHRS (3DM-GX3-25 class)", self.url, chans,
                          {"quaternion": "scalar-first, body->navigation, z up"})

    def read_block(self) -> Block:
        if self.closed:
            raise DeviceError("sim reference imu: read after close")
        self.faults.check(self.clock.now(), "read_block")
        t = self._sampler.due()
        if t.size == 0:
            return Block.empty(REFERENCE_IMU_CHANNELS)
        s = self.hexapod.state_at(t)
        n = t.size
        att = Rotation.from_euler("xyz", s.euler_rad)  # extrinsic x-y-z = Rz·Ry·Rx (Z-Y-X)
        att = att * Rotation.from_rotvec(self.rng.normal(0.0, self.attitude_noise_rad, (n, 3)))
        q = att.as_quat(canonical=True, scalar_first=True)
        w = s.omega_b_rad_s + self.rng.normal(0.0, self.gyro_noise_rad_s, (n, 3))
        data = np.hstack([q, w])
        block = Block(t, {c: data[:, i] for i, c in enumerate(REFERENCE_IMU_CHANNELS)})
        return self.faults.apply(block, dict.fromkeys(REFERENCE_IMU_CHANNELS, 1.0))

    def inject(self, fault: Fault | str, **kwargs: Unpack[FaultOptions]) -> None:
        self.faults.inject(fault, **kwargs)

    def close(self) -> None:
        self.closed = True
