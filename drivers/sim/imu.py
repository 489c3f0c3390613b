"""Simulated IMU under test (an ADIS16400 by default) mounted off-centre on the UAV.

Forward sensor model, in the IMU frame (Paper A, A.1-A.6 read from truth to reading)::

    gyro = S_w · N_w · Cᵀ · ω_b + b_w + noise
    acc  = S_a · N_a · Cᵀ · (f_b + α_b × R + ω_b × (ω_b × R)) + b_a + noise

``C`` is the IMU→body mounting rotation (A.15, Paper A measured ψ = 17°), ``N`` a
lower-triangular matrix of unit rows (axis non-orthogonality; x is the reference axis, y
lies in the x-y plane), ``S`` the per-axis scale factors, ``R`` the lever arm from the
centre of gravity to the IMU. The readings are clipped to the range and quantised to the
LSB. The correction matrix the calibration should find is ``K = (S·N·Cᵀ)⁻¹``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from drivers.sim.hexapod import HexapodState

__all__ = ["ADIS16400", "ImuModel", "SimImu", "nonorthogonal_axes"]

Array = NDArray[np.float64]
G = 9.80665


def nonorthogonal_axes(eps_deg: tuple[float, float, float]) -> Array:
    """Lower-triangular matrix whose unit rows are the sensitive axes.

    ``eps_deg = (xy, xz, yz)``: each pair of axes is ``90° - eps`` apart.
    """
    sxy, sxz, syz = np.sin(np.radians(eps_deg))
    n10, n11 = sxy, np.sqrt(1 - sxy**2)
    n20 = sxz
    n21 = (syz - n10 * n20) / n11
    n22 = np.sqrt(1 - n20**2 - n21**2)
    return np.array([[1.0, 0.0, 0.0], [n10, n11, 0.0], [n20, n21, n22]])


@dataclass(frozen=True)
class ImuModel:
    """Every error source of the simulated IMU, in SI units (datasheet figures noted)."""

    mounting_deg: tuple[float, float, float] = (0.0, 0.0, 17.0)  # φ, θ, ψ of (A.15)
    lever_arm_m: tuple[float, float, float] = (0.365, -0.235, 0.230)  # Paper A 4.3
    gyro_bias_rad_s: tuple[float, float, float] = (-0.0043, 0.0010, 0.0048)  # (A.12)
    acc_bias_m_s2: tuple[float, float, float] = (0.03, -0.02, 0.05)
    gyro_scale: tuple[float, float, float] = (1.004, 0.997, 1.002)
    acc_scale: tuple[float, float, float] = (0.996, 1.003, 1.005)
    gyro_nonorth_deg: tuple[float, float, float] = (0.10, -0.15, 0.05)
    acc_nonorth_deg: tuple[float, float, float] = (0.20, -0.10, 0.15)
    # ADIS16400 datasheet: rate noise density 0.05 °/s/√Hz, accel 0.5 mg/√Hz,
    # ±300 °/s and ±18 g, LSB 0.05 °/s and 3.33 mg.
    gyro_noise_density: float = float(np.radians(0.05))
    acc_noise_density: float = 0.5e-3 * G
    gyro_range_rad_s: float = float(np.radians(300.0))
    acc_range_m_s2: float = 18.0 * G
    gyro_lsb_rad_s: float = float(np.radians(0.05))
    acc_lsb_m_s2: float = 3.33e-3 * G
    clock_offset_s: float = 0.0237  # IMU samples lag the hexapod clock by this much
    rate_hz: float = 100.0

    def mounting(self) -> Array:
        """IMU→body rotation C of (A.15): ``Rz(ψ)·Ry(θ)·Rx(φ)``."""
        from scipy.spatial.transform import Rotation  # here: a propulsion run loads this
        # module through the rig file's IMU section, and scipy outlasts a short sim run

        return Rotation.from_euler("xyz", self.mounting_deg, degrees=True).as_matrix()

    def forward_gyro(self) -> Array:
        return np.diag(self.gyro_scale) @ nonorthogonal_axes(self.gyro_nonorth_deg) @ \
            self.mounting().T

    def forward_acc(self) -> Array:
        return np.diag(self.acc_scale) @ nonorthogonal_axes(self.acc_nonorth_deg) @ \
            self.mounting().T

    def k_gyro(self) -> Array:
        """The true correction matrix K_ω of (A.5)."""
        return np.asarray(np.linalg.inv(self.forward_gyro()), dtype=np.float64)

    def k_acc(self) -> Array:
        """The true correction matrix K_a of (A.3)."""
        return np.asarray(np.linalg.inv(self.forward_acc()), dtype=np.float64)

    def noise_std(self) -> tuple[float, float]:
        """White-noise standard deviation per sample (gyro, acc), bandwidth rate/2."""
        bw = np.sqrt(self.rate_hz / 2.0)
        return self.gyro_noise_density * bw, self.acc_noise_density * bw


ADIS16400 = ImuModel()


class SimImu:
    """Turns hexapod truth into IMU readings with a seeded random generator."""

    def __init__(self, model: ImuModel = ADIS16400, rng: np.random.Generator | None = None):
        self.model = model
        self.rng = rng if rng is not None else np.random.default_rng(0)

    def measure(self, truth: HexapodState) -> tuple[Array, Array]:
        """Gyro (rad/s) and accelerometer (m/s²) readings for each truth sample."""
        m = self.model
        r = np.asarray(m.lever_arm_m)
        w, a = truth.omega_b_rad_s, truth.alpha_b_rad_s2
        f_imu = truth.specific_force_b_m_s2 + np.cross(a, r) + np.cross(w, np.cross(w, r))
        sg, sa = m.noise_std()
        n = len(truth.t_s)
        gyro = w @ m.forward_gyro().T + np.asarray(m.gyro_bias_rad_s) + \
            self.rng.normal(0.0, sg, (n, 3))
        acc = f_imu @ m.forward_acc().T + np.asarray(m.acc_bias_m_s2) + \
            self.rng.normal(0.0, sa, (n, 3))
        gyro = np.round(np.clip(gyro, -m.gyro_range_rad_s, m.gyro_range_rad_s)
                        / m.gyro_lsb_rad_s) * m.gyro_lsb_rad_s
        acc = np.round(np.clip(acc, -m.acc_range_m_s2, m.acc_range_m_s2)
                       / m.acc_lsb_m_s2) * m.acc_lsb_m_s2
        return gyro, acc
