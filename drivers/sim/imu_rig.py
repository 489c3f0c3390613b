"""The simulated IMU bench: one clock, one hexapod, the IMU under test, a reference IMU.

All devices share a :class:`~drivers.sim.clock.SimClock` and read the same hexapod truth;
random streams are derived from one seed, so a rig file and a seed give the same run.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import Any

import numpy as np

from drivers.contracts import HexapodLimits
from drivers.sim.clock import SimClock
from drivers.sim.hexapod_device import SimHexapodDevice
from drivers.sim.imu import ImuModel
from drivers.sim.imu_device import SimImuDevice, SimReferenceImu

__all__ = ["SimImuRig", "imu_model"]


def imu_model(overrides: Mapping[str, Any], noise: bool = True) -> ImuModel:
    """ADIS16400 defaults with ``overrides`` (ImuModel field names, SI); noise off zeroes
    the noise densities. Unknown names raise ``KeyError``."""
    names = {f.name for f in dataclasses.fields(ImuModel)}
    unknown = sorted(set(overrides) - names)
    if unknown:
        raise KeyError(unknown[0])
    values = {k: (tuple(float(x) for x in v) if isinstance(v, list | tuple) else float(v))
              for k, v in overrides.items()}
    model = dataclasses.replace(ImuModel(), **values)
    if not noise:
        model = dataclasses.replace(model, gyro_noise_density=0.0, acc_noise_density=0.0)
    return model


class SimImuRig:
    """Simulated devices of the IMU bench (``sim://hexapod``, ``sim://imu``,
    ``sim://reference-imu``)."""

    def __init__(self, model: ImuModel, limits: HexapodLimits, *, seed: int = 0,
                 log_rate_hz: float = 1000.0, cg_m: tuple[float, float, float] = (0, 0, 0),
                 reference: Mapping[str, float] | None = None,
                 clock: SimClock | None = None) -> None:
        self.seed = int(seed)
        streams = np.random.SeedSequence(self.seed).spawn(3)
        self.clock = clock if clock is not None else SimClock()  # wire rigs: a paced clock
        self.model = model
        x, y, z = cg_m
        self.cg_m = (float(x), float(y), float(z))
        self.hexapod = SimHexapodDevice(self.clock, limits, log_rate_hz=log_rate_hz,
                                        rng=np.random.default_rng(streams[0]))
        self.imu = SimImuDevice(self.clock, self.hexapod, model,
                                np.random.default_rng(streams[1]), cg_m=self.cg_m)
        self.reference_imu = SimReferenceImu(self.clock, self.hexapod,
                                             np.random.default_rng(streams[2]),
                                             # the rig file's [reference_imu] numbers
                                             # (rate, noises), never the url
                                             **dict(reference or {}))  # pyright: ignore[reportArgumentType]

    def truth(self) -> dict[str, Any]:
        """What the calibration should find (K in the A.5 direction, R from the CG)."""
        m = self.model
        return {
            "k_gyro": m.k_gyro().tolist(),
            "k_acc": m.k_acc().tolist(),
            "gyro_bias_rad_s": list(m.gyro_bias_rad_s),
            "acc_bias_m_s2": list(m.acc_bias_m_s2),
            "lever_arm_m": list(m.lever_arm_m),
            "cg_m": list(self.cg_m),
            "mounting_deg": list(m.mounting_deg),
            "clock_offset_s": m.clock_offset_s,
            "gyro_noise_std_rad_s": m.noise_std()[0],
        }
