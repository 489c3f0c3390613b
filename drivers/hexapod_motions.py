"""Paper A's hexapod calibration motions as pure, analytic trajectories (device-free).

Used by the bench sequences for real and simulated hexapods alike, and by the simulators.

A :class:`Motion` is a sum of sines per degree of freedom (x, y, z in m; roll, pitch, yaw in
rad, Z-Y-X Euler angles of the platform about its pivot), faded in and out by a raised-cosine
envelope so that every motion starts and ends at rest at the home pose. Position, velocity
and acceleration are exact closed forms, so the simulated hexapod's truth has no
differentiation error.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = [
    "DOF",
    "Motion",
    "Phase",
    "acc_motion",
    "gyro_sines",
    "lever_arm_motion",
    "paper_a_protocol",
    "static_hold",
    "verification_motion",
]

DOF = ("x", "y", "z", "roll", "pitch", "yaw")
Array = NDArray[np.float64]

Term = tuple[float, float, float]  # amplitude (m or rad), frequency (Hz), phase (rad)


@dataclass(frozen=True)
class Motion:
    """A 6-DOF trajectory: ``terms[d]`` are the sines of degree of freedom ``DOF[d]``."""

    name: str
    duration_s: float
    terms: tuple[tuple[Term, ...], ...] = ((),) * 6
    ramp_s: float = 1.0

    def _envelope(self, t: Array) -> tuple[Array, Array, Array]:
        w, dw, ddw = np.ones_like(t), np.zeros_like(t), np.zeros_like(t)
        if self.ramp_s <= 0:
            inside = (t >= 0) & (t <= self.duration_s)
            return w * inside, dw, ddw
        k = np.pi / self.ramp_s
        for u, sign in ((t, 1.0), (self.duration_s - t, -1.0)):
            ramp = (u >= 0) & (u < self.ramp_s)
            w = np.where(ramp, 0.5 * (1 - np.cos(k * u)), w)
            dw = np.where(ramp, sign * 0.5 * k * np.sin(k * u), dw)
            ddw = np.where(ramp, 0.5 * k * k * np.cos(k * u), ddw)
        outside = (t < 0) | (t > self.duration_s)
        return (np.where(outside, 0.0, w), np.where(outside, 0.0, dw),
                np.where(outside, 0.0, ddw))

    def evaluate(self, t: ArrayLike) -> tuple[Array, Array, Array]:
        """Pose, its first and second time derivatives at times ``t`` (s), each ``(n, 6)``."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        w, dw, ddw = self._envelope(t)
        pose = np.zeros((t.size, 6))
        vel = np.zeros_like(pose)
        acc = np.zeros_like(pose)
        for d, terms in enumerate(self.terms):
            s = np.zeros_like(t)
            ds = np.zeros_like(t)
            dds = np.zeros_like(t)
            for amp, freq, phase in terms:
                om = 2 * np.pi * freq
                arg = om * t + phase
                s += amp * np.sin(arg)
                ds += amp * om * np.cos(arg)
                dds -= amp * om * om * np.sin(arg)
            pose[:, d] = w * s
            vel[:, d] = dw * s + w * ds
            acc[:, d] = ddw * s + 2 * dw * ds + w * dds
        return pose, vel, acc


@dataclass(frozen=True)
class Phase:
    """One recorded stage of the protocol: its log label and the motion the hexapod runs."""

    label: str
    motion: Motion


def _terms(**by_dof: Sequence[Term]) -> tuple[tuple[Term, ...], ...]:
    return tuple(tuple(by_dof.get(name, ())) for name in DOF)


def static_hold(samples: int = 10_000, rate_hz: float = 100.0) -> Motion:
    """Paper A section 4.1: the hexapod holds still while the gyro bias is averaged."""
    return Motion("static_hold", samples / rate_hz, ramp_s=0.0)


def gyro_sines(
    amplitude_deg: float = 4.0,
    freqs_hz: tuple[float, float, float] = (0.6, 0.65, 0.7),
    beats: int = 2,
    ramp_s: float = 1.0,
) -> Motion:
    """Paper A section 4.2: sines about x, y, z at different frequencies, whole common periods.

    0.6, 0.65 and 0.7 Hz repeat together every 1/gcd = 20 s; ``beats`` such periods make the
    three regressors orthogonal. The amplitude is the rotation angle (4°).
    """
    f = np.asarray(freqs_hz, dtype=float)
    gcd = np.gcd.reduce(np.round(f * 1000).astype(int)) / 1000.0
    amp = np.radians(amplitude_deg)
    duration = beats / gcd + 2 * ramp_s
    return Motion(
        "gyro_sines",
        duration,
        _terms(roll=[(amp, f[0], 0.0)], pitch=[(amp, f[1], 0.0)], yaw=[(amp, f[2], 0.0)]),
        ramp_s,
    )


def acc_motion(
    axis: str,
    rotation_deg: float = 15.0,
    rotation_hz: float = 0.01,
    translation_m: float = 0.04,
    translation_hz: tuple[float, float, float] = (1.1, 1.3, 1.5),
    ramp_s: float = 1.0,
) -> Motion:
    """Paper A section 3.2: rapid translations along x, y, z with a slow rotation about ``axis``.

    The slow rotation (one period of ``rotation_hz``) swings gravity across the IMU axes;
    the translations (different frequencies per axis) excite all three accelerometers.
    """
    rot = {"x": "roll", "y": "pitch", "z": "yaw"}[axis]
    tr = [(translation_m, f, 0.0) for f in translation_hz]
    terms = {"x": [tr[0]], "y": [tr[1]], "z": [tr[2]],
             rot: [(np.radians(rotation_deg), rotation_hz, 0.0)]}
    return Motion(f"acc_rot_{axis}", 1.0 / rotation_hz + 2 * ramp_s, _terms(**terms), ramp_s)


def lever_arm_motion(
    axis: str, amplitude_deg: float = 5.0, freq_hz: float = 0.7, duration_s: float = 30.0,
    ramp_s: float = 1.0,
) -> Motion:
    """Paper A section 4.3: a 5° sine at 0.7 Hz about one body axis."""
    rot = {"x": "roll", "y": "pitch", "z": "yaw"}[axis]
    terms = {rot: [(np.radians(amplitude_deg), freq_hz, 0.0)]}
    return Motion(f"lever_{axis}", duration_s, _terms(**terms), ramp_s)


def verification_motion(
    angle_deg: float = 5.0, position_m: float = 0.1, duration_s: float = 60.0,
    ramp_s: float = 1.0,
) -> Motion:
    """Paper A section 4.4: an independent multi-sine in all six DOF, 0-1 Hz, 5° and 0.1 m.

    Each DOF is three sines whose amplitudes add up to the stated range, with frequencies
    spread over 0.1-1 Hz and shifted per DOF so no two DOF share a frequency.
    """
    base_pos = np.array([0.11, 0.29, 0.53])
    base_ang = np.array([0.17, 0.41, 0.83])
    terms: dict[str, list[Term]] = {}
    for k, name in enumerate(DOF):
        angular = k >= 3
        freqs = (base_ang if angular else base_pos) + 0.023 * k
        amp = (np.radians(angle_deg) if angular else position_m) / 3.0
        terms[name] = [(amp, float(f), 0.7 * (j + k)) for j, f in enumerate(freqs)]
    return Motion("verification", duration_s, _terms(**terms), ramp_s)


def paper_a_protocol(rate_hz: float = 100.0, short: bool = False) -> list[Phase]:
    """The full calibration protocol of Paper A, in order, with the log's phase labels.

    ``short`` keeps every stage but shortens it for fast tests (bias 3000 samples, gyro
    sines kept at two 20 s beats, a 0.02 Hz slow rotation, 20 s lever-arm and 30 s
    verification motions); the accuracy targets still hold with the ADIS16400's noise.
    """
    if short:
        return [
            Phase("bias", static_hold(3000, rate_hz)),
            Phase("gyro", gyro_sines(beats=2)),
            *(Phase("acc", acc_motion(a, rotation_hz=0.02)) for a in "xyz"),
            *(Phase(f"lever_{a}", lever_arm_motion(a, duration_s=20.0)) for a in "xyz"),
            Phase("verify", verification_motion(duration_s=30.0)),
        ]
    return [
        Phase("bias", static_hold(10_000, rate_hz)),
        Phase("gyro", gyro_sines(beats=2)),
        *(Phase("acc", acc_motion(a)) for a in "xyz"),
        *(Phase(f"lever_{a}", lever_arm_motion(a)) for a in "xyz"),
        Phase("verify", verification_motion()),
    ]
