"""Disturbed and slowed variants of a real IMU recording with optical truth (BROAD-like).

Only one BROAD trial (07, undisturbed fast rotation) ships with the project; the benchmark
has others: slow rotation, translation, breaks, tapping, phone vibration, a magnet near
or on the sensor (Laidig et al., BROAD, Data 6(7), 2021). To check an attitude filter on
that family, these functions give trial 07 the *shapes* of those conditions, keeping its
real sensor noise, bias and motion:

* :func:`add_tapping`: finger taps, short damped accelerometer spikes of 2-6 g in random
  directions with a zero-mean gyro jolt (no net rotation: the truth does not move).
* :func:`add_translation`: sustained linear acceleration, an earth-frame sum of sines
  (0.25-0.8 Hz, ~3 m/s² horizontal) seen by the accelerometer as ``Rᵀ·a``.
* :func:`add_swing`: the recording's fast rotation made about a pivot ``lever_m`` away
  from the sensor (a hand turning a sensor it holds at the wrist or forearm): the sensor
  translates on a sphere and feels ``α×r + ω×(ω×r)``, the lever-arm terms of (A.18).
* :func:`add_vibration`: a vibrating phone, bursts of a 173 Hz sine (aliased at 286 Hz)
  on accelerometer and gyro.
* :func:`add_magnet_near`: a magnet passed near the sensor, an earth-frame field of tens
  of µT over seconds; :func:`add_magnet_attached`: a constant field fixed to the sensor.
* :func:`insert_breaks`: rests of ``length_s`` inside the motion, built from the
  recording's own initial rest (noise and bias), plus a slow gyro bias drift.
* :func:`slow_down`: the motion played ``factor`` times slower, the noise kept white at
  its measured level.

A recording is a dict of arrays as :mod:`drivers.sim.imu_tumble` returns: ``t_s``,
``gyro`` (rad/s), ``acc`` (m/s²), ``mag`` (µT), ``quat`` (truth, scalar-first, sensor to
ENU earth, NaN rows where the reference lost track) and ``movement`` (bool). No function
changes its input. Used by ``tests/analysis/test_attitude_broad_variants.py``,
``benchmarks/attitude_broad_variants.py`` and ``benchmarks/attitude_paper_b_tuning.py``.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray
from scipy.signal import savgol_filter
from scipy.spatial.transform import Rotation, Slerp

from drivers.sim.imu_tumble import Recording

__all__ = [
    "UNDISTURBED",
    "VARIANTS",
    "add_magnet_attached",
    "add_magnet_near",
    "add_swing",
    "add_tapping",
    "add_translation",
    "add_vibration",
    "fill_gaps",
    "insert_breaks",
    "make_variant",
    "slow_down",
]

Array = NDArray[np.float64]
G = 9.80665


def fill_gaps(q: Array) -> Array:
    """Truth quaternions with NaN rows replaced by the nearest finite row (for rotating)."""
    q = np.asarray(q, dtype=float)
    ok = np.isfinite(q).all(axis=1)
    if not ok.any():
        raise ValueError("the reference has no finite quaternion")
    idx = np.flatnonzero(ok)
    pos = np.clip(np.searchsorted(idx, np.arange(len(q))), 0, len(idx) - 1)
    prev = idx[np.maximum(pos - 1, 0)]
    nxt = idx[pos]
    near = np.where(np.abs(np.arange(len(q)) - prev) <= np.abs(nxt - np.arange(len(q))),
                    prev, nxt)
    return q[near]


def _rot(q: Array) -> Rotation:
    return Rotation.from_quat(fill_gaps(q)[:, [1, 2, 3, 0]])  # scipy is scalar-last


def _to_sensor(q: Array, v_earth: Array) -> Array:
    """``Rᵀ·v``: earth-frame vectors ``(n, 3)`` in the sensor frame of truth ``q``."""
    return _rot(q).inv().apply(v_earth)


def _movement_gate(rec: Recording, ramp_s: float = 1.0) -> Array:
    """1 inside the movement phase, raised-cosine ramps of ``ramp_s`` at its ends."""
    t, mov = rec["t_s"], rec["movement"].astype(float)
    dt = float(np.median(np.diff(t)))
    n = max(1, round(ramp_s / dt))
    kernel = np.hanning(2 * n + 1)
    return np.clip(np.convolve(mov, kernel / kernel.sum(), mode="same"), 0.0, 1.0)


def _copy(rec: Recording, **changes: Array) -> Recording:
    out = {k: np.array(v, copy=True) for k, v in rec.items()}
    out.update(changes)
    return out


def add_tapping(rec: Recording, seed: int = 0, mean_interval_s: float = 0.7,
                peak_g: tuple[float, float] = (2.0, 6.0), gyro_jolt_rad_s: float = 1.0
                ) -> Recording:
    """Taps during the movement phase: accelerometer spikes, a gyro jolt with no net turn.

    Each tap: ``A·d·exp(-τ/8 ms)·sin(2π·40 Hz·τ)`` on the accelerometer (d a random unit
    vector, A drawn in ``peak_g``) and a derivative-of-Gaussian gyro pulse (σ = 10 ms,
    integral zero) about a random axis.
    """
    rng = np.random.default_rng(seed)
    t = rec["t_s"]
    acc, gyro = rec["acc"].copy(), rec["gyro"].copy()
    moving = t[rec["movement"]]
    taps = []
    s = moving[0] + rng.exponential(mean_interval_s)
    while s < moving[-1]:
        taps.append(s)
        s += rng.exponential(mean_interval_s)
    for t0 in taps:
        k0 = int(np.searchsorted(t, t0))
        sl = slice(max(0, k0 - 10), min(len(t), k0 + 30))
        tau = t[sl] - t0
        d = rng.standard_normal(3)
        d /= np.linalg.norm(d)
        amp = rng.uniform(*peak_g) * G
        pulse = np.where(tau >= 0, np.exp(-tau / 0.008) * np.sin(2 * np.pi * 40.0 * tau), 0.0)
        acc[sl] += amp * pulse[:, None] * d
        axis = rng.standard_normal(3)
        axis /= np.linalg.norm(axis)
        jolt = -tau / 0.01 * np.exp(-0.5 * (tau / 0.01) ** 2)  # zero integral
        gyro[sl] += gyro_jolt_rad_s * jolt[:, None] * axis
    return _copy(rec, acc=acc, gyro=gyro)


def add_translation(rec: Recording, seed: int = 0, horizontal_m_s2: float = 3.0,
                    vertical_m_s2: float = 1.5) -> Recording:
    """Sustained linear acceleration during the movement phase, seen as ``Rᵀ·a_earth``."""
    rng = np.random.default_rng(seed)
    t = rec["t_s"]
    a = np.zeros((len(t), 3))
    for axis, amp in ((0, horizontal_m_s2), (1, horizontal_m_s2), (2, vertical_m_s2)):
        for f in rng.uniform(0.25, 0.8, size=2):
            a[:, axis] += amp / 2 * np.sin(2 * np.pi * f * t + rng.uniform(0, 2 * np.pi))
    a *= _movement_gate(rec)[:, None]
    return _copy(rec, acc=rec["acc"] + _to_sensor(rec["quat"], a))


def add_swing(rec: Recording, lever_m: tuple[float, float, float] = (0.0, 0.1, 0.0),
              window: int = 15) -> Recording:
    """The motion about a pivot at ``-lever_m`` (sensor frame, m): add ``α×r + ω×(ω×r)``.

    The sensor then sits at ``R·r`` from a fixed pivot, a bounded position, so the added
    earth-frame acceleration averages to zero over the motion, but it is large (ω of
    5-20 rad/s: ω²r of 2.5-40 m/s² at 10 cm) and its centripetal part always points to the
    pivot. ω and α are the gyro smoothed and differentiated by a Savitzky-Golay filter
    (``window`` samples, quadratic; 52 ms at 286 Hz), so the gyro's noise is not
    differentiated; the gyro itself is kept.
    """
    dt = float(np.median(np.diff(rec["t_s"])))
    w = np.asarray(savgol_filter(rec["gyro"], window, 2, axis=0))
    alpha = np.asarray(savgol_filter(rec["gyro"], window, 2, deriv=1, delta=dt, axis=0))
    r = np.asarray(lever_m, dtype=float)
    return _copy(rec, acc=rec["acc"] + np.cross(alpha, r) + np.cross(w, np.cross(w, r)))


def add_vibration(rec: Recording, seed: int = 0, freq_hz: float = 173.0,
                  acc_m_s2: float = 4.0, gyro_rad_s: float = 0.1, on_s: float = 1.5,
                  off_s: float = 1.0) -> Recording:
    """Bursts (``on_s`` on, ``off_s`` off) of a phone's vibration motor during movement."""
    rng = np.random.default_rng(seed)
    t = rec["t_s"]
    burst = ((t % (on_s + off_s)) < on_s) & rec["movement"]
    ph_a, ph_g = rng.uniform(0, 2 * np.pi, 3), rng.uniform(0, 2 * np.pi, 3)
    wave_a = np.sin(2 * np.pi * freq_hz * t[:, None] + ph_a) * burst[:, None]
    wave_g = np.sin(2 * np.pi * freq_hz * t[:, None] + ph_g) * burst[:, None]
    return _copy(rec, acc=rec["acc"] + acc_m_s2 * wave_a,
                 gyro=rec["gyro"] + gyro_rad_s * wave_g)


def add_magnet_near(rec: Recording, seed: int = 0, peak_ut: tuple[float, float] = (20.0, 60.0),
                    every_s: float = 12.0, length_s: tuple[float, float] = (2.0, 6.0)
                    ) -> Recording:
    """A magnet near the path: earth-frame field bumps (raised cosine) of tens of µT."""
    rng = np.random.default_rng(seed)
    t = rec["t_s"]
    moving = t[rec["movement"]]
    extra = np.zeros((len(t), 3))
    start = moving[0] + rng.uniform(0, every_s)
    while start < moving[-1]:
        length = rng.uniform(*length_s)
        x = np.clip((t - start) / length, 0.0, 1.0)
        bump = 0.5 - 0.5 * np.cos(2 * np.pi * x)
        d = rng.standard_normal(3)
        extra += rng.uniform(*peak_ut) * bump[:, None] * d / np.linalg.norm(d)
        start += every_s * rng.uniform(0.6, 1.4)
    return _copy(rec, mag=rec["mag"] + _to_sensor(rec["quat"], extra))


def add_magnet_attached(rec: Recording, field_ut: tuple[float, float, float] = (25.0, -10.0,
                                                                                 15.0)
                        ) -> Recording:
    """A magnet fixed next to the sensor: a constant field in the sensor frame."""
    return _copy(rec, mag=rec["mag"] + np.asarray(field_ut, dtype=float))


def _rest_slice(rec: Recording, seconds: float) -> slice:
    """The longest stretch at the start with a finite truth and no movement."""
    ok = np.isfinite(rec["quat"]).all(axis=1) & ~rec["movement"]
    first = int(np.argmax(ok))
    n = round(seconds / float(np.median(np.diff(rec["t_s"]))))
    if first + n > len(ok) or not ok[first:first + n].all():
        raise ValueError(f"the recording has no {seconds:g} s rest with truth at its start")
    return slice(first, first + n)


def insert_breaks(rec: Recording, at_fraction: tuple[float, ...] = (0.3, 0.55, 0.8),
                  length_s: float = 10.0, bias_drift_rad_s: float = 0.015) -> Recording:
    """Rests of ``length_s`` inserted in the movement phase, then a gyro bias drift.

    A rest holds the true orientation at its start: gyro = the recording's initial rest
    (its real noise and bias), accelerometer and magnetometer = gravity and the earth's
    field (both measured in that rest) turned into the sensor frame, plus that rest's
    noise. The rests count as movement (scored). Afterwards a bias ramping from 0 to
    ``bias_drift_rad_s`` over the recording (about x, -y, z) is added to the gyro, which
    only a filter that estimates the bias (at rest or in motion) removes.
    """
    rest = _rest_slice(rec, length_s)
    q_rest = fill_gaps(rec["quat"])[rest]
    r_rest = Rotation.from_quat(q_rest[:, [1, 2, 3, 0]])
    g_earth = r_rest.apply(rec["acc"][rest]).mean(axis=0)
    m_earth = r_rest.apply(rec["mag"][rest]).mean(axis=0)
    noise_a = rec["acc"][rest] - rec["acc"][rest].mean(axis=0)
    noise_m = rec["mag"][rest] - rec["mag"][rest].mean(axis=0)
    moving = np.flatnonzero(rec["movement"])
    cuts = sorted(int(moving[0] + f * (moving[-1] - moving[0])) for f in at_fraction)
    n_rest = rest.stop - rest.start
    parts: dict[str, list[Array]] = {k: [] for k in ("gyro", "acc", "mag", "quat", "movement")}
    prev = 0
    q_all = fill_gaps(rec["quat"])
    for k in [*cuts, len(rec["t_s"])]:
        for key in parts:
            parts[key].append(rec[key][prev:k])
        if k < len(rec["t_s"]):
            q = q_all[k]
            r = Rotation.from_quat(q[[1, 2, 3, 0]])
            parts["gyro"].append(rec["gyro"][rest])
            parts["acc"].append(r.inv().apply(g_earth) + noise_a)
            parts["mag"].append(r.inv().apply(m_earth) + noise_m)
            parts["quat"].append(np.tile(q, (n_rest, 1)))
            parts["movement"].append(np.ones(n_rest, dtype=bool))
        prev = k
    out = {k: np.concatenate(v) for k, v in parts.items()}
    n = len(out["gyro"])
    dt = float(np.median(np.diff(rec["t_s"])))
    out["t_s"] = rec["t_s"][0] + np.arange(n) * dt
    drift = np.array([1.0, -1.0, 1.0]) / np.sqrt(3.0) * bias_drift_rad_s
    out["gyro"] = out["gyro"] + np.linspace(0.0, 1.0, n)[:, None] * drift
    return out


def slow_down(rec: Recording, factor: float = 3.0, seed: int = 0, rest_s: float = 10.0
              ) -> Recording:
    """The motion ``factor`` times slower at the same sampling rate.

    Sample j reads the recording at ``j/factor`` (linear interpolation; truth by slerp):
    the gyro's rate part is divided by ``factor`` around the bias of the initial rest, the
    accelerometer and magnetometer are kept (conservative: the real linear acceleration
    would shrink by ``factor²``). Interpolating between samples (and the gyro's division)
    lowers the white noise; fresh noise restores the level measured in the initial rest.
    """
    rng = np.random.default_rng(seed)
    rest = _rest_slice(rec, rest_s)
    n0 = len(rec["t_s"])
    src = np.arange(int((n0 - 1) * factor) + 1) / factor
    lo = np.minimum(np.floor(src).astype(int), n0 - 2)
    u = (src - lo)[:, None]

    def lerp(x: Array) -> Array:
        return (1 - u) * x[lo] + u * x[lo + 1]

    def renoise(x: Array, std: Array, scale: float = 1.0) -> Array:
        # white noise of std σ interpolated and scaled keeps σ·scale·√((1-u)² + u²)
        kept = scale**2 * ((1 - u) ** 2 + u**2)
        return x + np.sqrt(np.clip(1 - kept, 0.0, 1.0)) * std * rng.standard_normal(x.shape)

    bias = rec["gyro"][rest].mean(axis=0)
    gyro = renoise((lerp(rec["gyro"]) - bias) / factor + bias, rec["gyro"][rest].std(axis=0),
                   1.0 / factor)
    acc = renoise(lerp(rec["acc"]), rec["acc"][rest].std(axis=0))
    mag = renoise(lerp(rec["mag"]), rec["mag"][rest].std(axis=0))
    q = rec["quat"]
    finite = np.all(np.isfinite(q), axis=1)
    quat = Slerp(np.arange(n0), _rot(q))(np.clip(src, 0, n0 - 1)).as_quat()[:, [3, 0, 1, 2]]
    quat[~(finite[lo] & finite[lo + 1])] = np.nan
    movement = rec["movement"][lo] & rec["movement"][lo + 1]
    dt = float(np.median(np.diff(rec["t_s"])))
    return {"t_s": rec["t_s"][0] + np.arange(len(src)) * dt, "gyro": gyro, "acc": acc,
            "mag": mag, "quat": quat, "movement": movement}


def _mixed(rec: Recording, seed: int) -> Recording:
    out = add_translation(rec, seed, horizontal_m_s2=1.5, vertical_m_s2=0.75)
    out = add_tapping(out, seed + 1, mean_interval_s=2.0)
    out = add_vibration(out, seed + 2, on_s=1.0, off_s=4.0)
    return add_magnet_near(out, seed + 3)


def _combined_with_breaks(rec: Recording, seed: int) -> Recording:
    """Fast rotation at a 12 cm lever arm with strong translation (6 m/s² horizontal,
    3 m/s² vertical), in four ~30 s movement phases split by 10 s rests."""
    out = add_translation(add_swing(rec, (0.07, 0.07, -0.07)), seed, 6.0, 3.0)
    return insert_breaks(out, at_fraction=(0.25, 0.5, 0.75))


# name -> builder (recording, seed); BROAD's groups: undisturbed (slow, breaks, translation,
# fast rotation combined with translation) and disturbed (tapping, vibration, stationary
# and attached magnet, mixed)
VARIANTS: dict[str, Callable[[Recording, int], Recording]] = {
    "slow_rotation": lambda r, s: slow_down(r, 3.0, s),
    "with_breaks": lambda r, s: insert_breaks(r),
    "translation": add_translation,
    "swing_wrist": lambda r, s: add_swing(r, (0.0, 0.1, 0.0)),
    "swing_forearm": lambda r, s: add_swing(r, (0.12, 0.12, -0.1)),
    "combined_with_breaks": _combined_with_breaks,
    "tapping": add_tapping,
    "vibration": add_vibration,
    "stationary_magnet": add_magnet_near,
    "attached_magnet": lambda r, s: add_magnet_attached(r),
    "mixed": _mixed,
}
UNDISTURBED = ("slow_rotation", "with_breaks", "translation", "swing_wrist", "swing_forearm",
               "combined_with_breaks")


def make_variant(rec: Recording, name: str, seed: int = 0) -> Recording:
    """One named variant of ``rec`` (see :data:`VARIANTS`)."""
    if name not in VARIANTS:
        raise ValueError(f"unknown variant {name!r}; known: {', '.join(VARIANTS)}")
    return VARIANTS[name](rec, seed)
