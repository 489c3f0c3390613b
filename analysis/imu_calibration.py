"""IMU calibration against a 6-DOF hexapod (thesis Paper A), from a calibration log.

Model direction (as in Paper A): the correction matrices map bias-free IMU readings to the
body frame, ``ω_b = K_ω (ω̃ - b_ω)`` (A.5-A.6) and
``f_cg = K_a (ã - b_a) - ω×(ω×R) - α×R`` (A.3, A.17-A.18). The hexapod clock is the
reference: the IMU row stamped ``t`` was measured at ``t - time_offset_s``.

Stages: gyro bias from the static hold (A.12); the time offset by cross-correlating |ω|
and refining on the least-squares residual; K by least squares (A.7-A.9) with a
conditioning check; the lever arm R from (A.10)-(A.11); the split of K into mounting
rotation, scale and non-orthogonality (A.15-A.16); verification RMS (A.19, Table A.2).
"""

from __future__ import annotations

import itertools
import json
import math
import warnings
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from numpy.typing import NDArray
from scipy.interpolate import CubicSpline
from scipy.optimize import minimize_scalar
from scipy.signal import correlate, correlation_lags, savgol_filter
from scipy.spatial.transform import Rotation

from analysis.atomic_files import write_atomically
from analysis.errors import CalibrationError, LogError
from analysis.imu_log import (
    IMU_ACC,
    IMU_GYRO,
    MAG_COLUMNS,
    REF_ACC,
    REF_ALPHA,
    REF_OMEGA,
    imu_columns,
)

__all__ = [
    "ADIS16400_ACC_RANGE_M_S2",
    "ADIS16400_GYRO_RANGE_RAD_S",
    "DECOMPOSITION_CONVENTION",
    "TABLE_A2",
    "Calibration",
    "aligned_phase",
    "angular_acceleration",
    "apply_calibration",
    "apply_to_frame",
    "calibrate",
    "decompose",
    "estimate_time_offset",
    "excitation_condition",
    "fit_forward",
    "load_calibration",
    "save_calibration",
]

Array = NDArray[np.float64]
XYZ = ("x", "y", "z")
G = 9.80665
ADIS16400_GYRO_RANGE_RAD_S = math.radians(300.0)  # ADIS16400 datasheet, ±300 °/s
ADIS16400_ACC_RANGE_M_S2 = 18.0 * G  # ±18 g
# Table A.2 (corrected verification RMS). The table's unit label says °/s for ω, but the
# conclusions (0.01-0.015 rad/s = 0.25 % of ±300 °/s) show the numbers are rad/s.
TABLE_A2 = {"acc_m_s2": (0.264, 0.058, 0.177), "gyro_rad_s": (0.0123, 0.0123, 0.0107)}
DECOMPOSITION_CONVENTION = (
    "K⁻¹ = M·Cᵀ (QR); C: IMU→body rotation, proper, Euler angles φ,θ,ψ of (A.15) "
    "C = Rz(ψ)Ry(θ)Rx(φ); M lower-triangular with positive diagonal: IMU x axis is the "
    "reference, y lies in the x-y plane; scale_i = ‖row i of M‖; non-orthogonality = "
    "90° minus the angle between sensitive axes (xy, xz, yz)"
)
# Table A.1 structure: rotating about axis i, accel component j gives R_k·sign·α_i (A.11).
_TANGENTIAL = {("x", "y"): ("z", -1.0), ("x", "z"): ("y", 1.0), ("y", "x"): ("z", 1.0),
               ("y", "z"): ("x", -1.0), ("z", "x"): ("y", -1.0), ("z", "y"): ("x", 1.0)}


@dataclass
class Calibration:
    """Everything a calibration found; ``to_dict`` is the JSON file's content."""

    gyro_bias_rad_s: list[float]
    gyro_bias_stderr_rad_s: list[float]
    acc_bias_m_s2: list[float]
    k_gyro: list[list[float]]
    k_acc: list[list[float]]
    lever_arm_m: list[float]
    time_offset_s: float
    verification_rms: dict[str, Any] | None = None
    lever_arm_estimates: dict[str, Any] = field(default_factory=dict)
    decomposition: dict[str, Any] = field(default_factory=dict)
    conditioning: dict[str, float] = field(default_factory=dict)
    ranges: dict[str, float] = field(default_factory=lambda: {
        "gyro_rad_s": ADIS16400_GYRO_RANGE_RAD_S, "acc_m_s2": ADIS16400_ACC_RANGE_M_S2})
    warnings: list[str] = field(default_factory=list)
    source: str = ""
    model: str = ("ω_b = K_ω(ω̃ - gyro_bias); f_cg = K_a(ã - acc_bias) - ω×(ω×R) - α×R; "
                  "IMU row stamped t was measured at reference time t - time_offset_s")
    format: str = "rotorbench-imu-calibration/1"

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)

    @property
    def kg(self) -> Array:
        return np.asarray(self.k_gyro, dtype=float)

    @property
    def ka(self) -> Array:
        return np.asarray(self.k_acc, dtype=float)


# ----------------------------------------------------------------------------- helpers
def _blocks(mask: NDArray[np.bool_]) -> list[slice]:
    """Contiguous runs of True in a boolean mask."""
    idx = np.flatnonzero(np.diff(np.r_[0, mask.astype(np.int8), 0]))
    return [slice(int(s), int(e)) for s, e in zip(idx[::2], idx[1::2], strict=True)]


def _segments(t: Array, gap_factor: float = 1.5, min_gap_s: float = 0.0) -> list[slice]:
    """Split a time vector at gaps larger than ``gap_factor`` median sample periods (and
    than ``min_gap_s``)."""
    if len(t) < 2:
        return [slice(0, len(t))]
    dt = np.diff(t)
    cuts = np.flatnonzero(dt > max(gap_factor * np.median(dt), min_gap_s)) + 1
    edges = np.r_[0, cuts, len(t)]
    return [slice(int(a), int(b)) for a, b in itertools.pairwise(edges)]


def angular_acceleration(t: Array, omega: Array, window_s: float = 0.15) -> Array:
    """Angular acceleration from rate samples by a Savitzky-Golay derivative per segment.

    A plain difference of a 100 Hz ADIS16400 gyro has ~0.9 rad/s² of noise, which through
    a 0.4 m lever arm alone exceeds Table A.2; the local quadratic fit keeps it ~0.02.

    Savitzky-Golay assumes one sample period. Rows of a host-stamped serial IMU (MSP
    polled) are unevenly spaced and some are missing: such a segment is resampled onto its
    own uniform grid (its mean period, linear interpolation), differentiated there, and
    the derivative interpolated back onto the stamps. Segments break only at gaps longer
    than half the window (shorter ones are bridged by the grid).
    """
    out = np.empty_like(omega)
    for seg in _segments(t, min_gap_s=0.5 * window_s):
        ts, ws = t[seg], omega[seg]
        if len(ts) < 3:
            out[seg] = 0.0
            continue
        dt = float(ts[-1] - ts[0]) / (len(ts) - 1)  # mean period
        even = bool(np.all(np.abs(np.diff(ts) - dt) <= 1e-3 * dt))
        grid = ts if even else np.linspace(ts[0], ts[-1], len(ts))
        wg = ws if even else np.column_stack([np.interp(grid, ts, c) for c in ws.T])
        win = max(5, round(window_s / dt) | 1)
        if win > len(grid):
            d = np.gradient(wg, grid, axis=0)
        else:
            d = np.asarray(savgol_filter(wg, win, 2, deriv=1, delta=dt, axis=0))
        out[seg] = d if even else np.column_stack([np.interp(ts, grid, c) for c in d.T])
    return out


def excitation_condition(regressor: Array, centred: bool) -> float:
    """Condition number of the motion's 3-column regressor (∞ when an axis is not excited)."""
    x = regressor - regressor.mean(axis=0) if centred else regressor
    s = np.linalg.svd(x, compute_uv=False)
    return float(s[0] / s[-1]) if s[-1] > 0 else math.inf


def _check_condition(name: str, cond: float, warn_at: float, refuse_at: float,
                     notes: list[str]) -> None:
    if not cond < refuse_at:
        raise CalibrationError(
            f"{name} motion does not excite all three axes independently (condition number "
            f"{cond:.3g} ≥ {refuse_at:g}); K would be unreliable. Use different frequencies "
            "per axis over whole common periods (Paper A section 4.2), not the same "
            "frequency in phase or in antiphase"
        )
    if cond > warn_at:
        msg = f"{name} motion is poorly conditioned (condition number {cond:.3g} > {warn_at:g})"
        notes.append(msg)
        warnings.warn(msg, stacklevel=3)


def fit_forward(truth: Array, reading: Array, intercept: bool) -> tuple[Array, Array]:
    """Least squares ``reading ≈ F·truth (+ b)`` (A.7-A.9); returns ``(F, b)``.

    The exact hexapod signal is the regressor and the noisy IMU the response, so the noise
    does not bias F (fitting (A.9) the other way round shrinks K by σ²/rms², ~0.1 % for the
    gyro here); ``K = F⁻¹``.
    """
    x = np.c_[truth, np.ones(len(truth))] if intercept else truth
    coef, *_ = np.linalg.lstsq(x, reading, rcond=None)
    f = np.asarray(coef[:3].T, dtype=np.float64)
    b = np.asarray(coef[3], dtype=np.float64) if intercept else np.zeros(3)
    return f, b


# ----------------------------------------------------------------------- time offset
WALK_ROWS = 10  # how far the offset's refinement may move from the correlation's peak


def estimate_time_offset(t: Array, ref_omega: Array, gyro: Array, bias: Array,
                         max_lag_s: float = 0.5) -> float:
    """Lag of the IMU behind the reference (s): |ω| cross-correlation, then LS refinement.

    The norm makes the correlation independent of the mounting rotation and scale
    (Kalibr's recipe); the parabola through the peak and a bounded 1-D search on the
    residual of the K fit refine it below a sample period. The correlation counts lags in
    rows: rows missing here and there (a device that drops some) are put on an even grid
    of the median step first, or the lag in rows is not the lag in time.
    """
    dt = float(np.median(np.diff(t)))
    grid = t[0] + dt * np.arange(int((t[-1] - t[0]) / dt) + 1)
    a = np.interp(grid, t, np.linalg.norm(ref_omega, axis=1))
    b = np.interp(grid, t, np.linalg.norm(gyro - bias, axis=1))
    a, b = a - a.mean(), b - b.mean()
    c = correlate(b, a, mode="full", method="fft")
    lags = correlation_lags(len(b), len(a), mode="full")
    # a lag beyond the log is no limit (and 1e308 s / dt would not round to an integer)
    keep = np.abs(lags) <= max(1, round(min(max_lag_s / dt, len(lags))))
    c, lags = c[keep], lags[keep]
    k = int(np.argmax(c))
    shift = float(lags[k])
    if 0 < k < len(c) - 1:
        y0, y1, y2 = c[k - 1], c[k], c[k + 1]
        den = y0 - 2 * y1 + y2
        if den < 0:
            shift += 0.5 * (y0 - y2) / den
    coarse = shift * dt
    spline = CubicSpline(t, ref_omega, axis=0)
    trim = math.ceil(abs(coarse) / dt) + WALK_ROWS + 3
    inner = slice(trim, len(t) - trim)
    y = gyro[inner] - bias

    def cost(d: float) -> float:
        x = spline(t[inner] - d)
        coef, *_ = np.linalg.lstsq(x, y, rcond=None)
        return float(np.sum((y - x @ coef) ** 2))

    # a minimum on the window's edge is none: the window moves on, by up to WALK_ROWS (a
    # correlation peak of slow motion is broad, and gaps and jitter move it by more than
    # two rows when the rows are close)
    lo, hi = coarse - 2 * dt, coarse + 2 * dt
    while True:
        res = minimize_scalar(cost, bounds=(lo, hi), method="bounded",
                              options={"xatol": 1e-6})
        d = float(res.x)
        step = 2 * dt * (int(hi - d < 1e-4) - int(d - lo < 1e-4))
        if not step or abs(d + step - coarse) > WALK_ROWS * dt:
            return d
        lo, hi = lo + step, hi + step
    return d


def aligned_phase(df: pd.DataFrame, label: str, offset: float) -> dict[str, Array]:
    """Rows of one phase with the reference moved to the IMU's sampling instants."""
    mask = (df["phase"] == label).to_numpy()
    t_all = df["t_s"].to_numpy()
    out: dict[str, list[Array]] = {k: [] for k in ("t", "omega", "alpha", "f", "gyro", "acc")}
    for blk in _blocks(mask):
        t = t_all[blk]
        ref = df[list(REF_OMEGA + REF_ALPHA + REF_ACC)].to_numpy()[blk]
        ts = t - offset
        ok = (ts >= t[0]) & (ts <= t[-1])
        if ok.sum() < 4 or len(t) < 4:
            continue
        r = CubicSpline(t, ref, axis=0)(ts[ok])
        out["t"].append(t[ok])
        out["omega"].append(r[:, 0:3])
        out["alpha"].append(r[:, 3:6])
        out["f"].append(r[:, 6:9])
        out["gyro"].append(df[list(IMU_GYRO)].to_numpy()[blk][ok])
        out["acc"].append(df[list(IMU_ACC)].to_numpy()[blk][ok])
    if not out["t"]:
        raise LogError(f"{df.attrs.get('path', 'log')}: phase {label!r} has too few rows")
    return {k: np.concatenate(v) for k, v in out.items()}


# ------------------------------------------------------------------------ lever arm
def _lever_arm(phases: dict[str, dict[str, Array]], k_acc: Array, acc_bias: Array
               ) -> dict[str, Any]:
    """Lever arm from the three single-axis rotations, (A.10)-(A.11), Table A.1 layout."""
    alpha_est: dict[str, dict[str, float]] = {}
    omega2_est: dict[str, dict[str, float]] = {}
    for i, ax in enumerate(XYZ):
        d = phases[f"lever_{ax}"]
        y = (d["acc"] - acc_bias) @ k_acc.T - d["f"]  # α×R + ω×(ω×R) (A.3)
        x = np.c_[d["alpha"][:, i], d["omega"][:, i] ** 2, np.ones(len(y))]
        alpha_est[ax], omega2_est[ax] = {}, {}
        for j, comp in enumerate(XYZ):
            if comp == ax:
                continue
            (c_alpha, c_omega2, _), *_ = np.linalg.lstsq(x, y[:, j], rcond=None)
            k, sign = _TANGENTIAL[(ax, comp)]
            alpha_est[ax][k] = float(sign * c_alpha)  # (A.11)
            omega2_est[ax][comp] = float(-c_omega2)  # ω² column of (A.10)
    r = np.zeros(3)
    agreement = np.zeros(3)
    for k, comp in enumerate(XYZ):
        pair = [alpha_est[ax][comp] for ax in XYZ if comp in alpha_est[ax]]
        r[k] = float(np.mean(pair))
        agreement[k] = float(abs(pair[0] - pair[1]))
    return {"r": r, "alpha": alpha_est, "omega2": omega2_est, "agreement": agreement}


# --------------------------------------------------------------------- decomposition
def decompose(k: Array, measured_mounting_deg: tuple[float, float, float] | None = None
              ) -> dict[str, Any]:
    """Split K into mounting rotation, scale and non-orthogonality (see the convention)."""
    f = np.linalg.inv(np.asarray(k, dtype=float))
    q, u = np.linalg.qr(f.T)  # fᵀ = q·u  ⇒  f = uᵀ·qᵀ = M·Cᵀ
    d = np.diag(np.sign(np.diag(u)))
    u, q = d @ u, q @ d
    m, c = u.T, q
    if np.linalg.det(c) < 0:
        raise CalibrationError("K contains a reflection (det < 0): an axis sign is flipped; "
                               "check the IMU's axis signs and the log's column order")
    scale = np.linalg.norm(m, axis=1)
    n = m / scale[:, None]
    nonorth = [math.degrees(math.asin(float(n[a] @ n[b]))) for a, b in ((0, 1), (0, 2), (1, 2))]
    euler = Rotation.from_matrix(c).as_euler("xyz", degrees=True)  # C = Rz·Ry·Rx (A.15)
    out: dict[str, Any] = {
        "rotation_imu_to_body": c.tolist(),
        "euler_deg": [float(v) for v in euler],
        "scale": scale.tolist(),
        "nonorthogonality_deg": nonorth,
    }
    if measured_mounting_deg is not None:
        cm = Rotation.from_euler("xyz", measured_mounting_deg, degrees=True)
        err = (cm.inv() * Rotation.from_matrix(c)).magnitude()
        out["measured_mounting_deg"] = [float(v) for v in measured_mounting_deg]
        out["rotation_vs_measured_deg"] = float(math.degrees(err))
    return out


# ---------------------------------------------------------------------- application
def apply_calibration(cal: Calibration, t: Array, gyro: Array, acc: Array
                      ) -> tuple[Array, Array, Array]:
    """Correct IMU samples: ``(t_ref, ω_b, f_cg)`` by (A.17)-(A.18) and the time offset."""
    w = (gyro - np.asarray(cal.gyro_bias_rad_s)) @ cal.kg.T  # (A.17)
    alpha = angular_acceleration(t, w)
    r = np.asarray(cal.lever_arm_m)
    f = (acc - np.asarray(cal.acc_bias_m_s2)) @ cal.ka.T \
        - np.cross(w, np.cross(w, r)) - np.cross(alpha, r)  # (A.18)
    return t - cal.time_offset_s, w, f


def apply_to_frame(cal: Calibration, df: pd.DataFrame) -> pd.DataFrame:
    """Calibrated copy of an IMU log on its own rows (the reference clock).

    Adds/replaces ``gyro_*_rad_s`` (body rate) and ``acc_*_m_s2`` (specific force at the
    centre of gravity, body frame). The IMU data are moved by ``time_offset_s`` and
    linearly interpolated back onto the log's rows; rows the shift leaves without IMU data
    are dropped. A magnetometer (``mag_*_ut``) sits in the same package: Paper A does not
    calibrate it, but it is moved by the same offset and turned into the body frame by
    K_ω's mounting rotation (:func:`decompose`), so that a 9D filter fuses one frame.
    Other columns are copied unchanged.
    """
    gcols, acols = imu_columns(df)
    t = df["t_s"].to_numpy(dtype=float)
    has_mag = all(c in df.columns for c in MAG_COLUMNS)
    mag = df[list(MAG_COLUMNS)].to_numpy(float) if has_mag else np.zeros((len(t), 0))
    out_w = np.full((len(t), 3), np.nan)
    out_f = np.full((len(t), 3), np.nan)
    out_m = np.full(mag.shape, np.nan)
    for seg in _segments(t):
        ts = t[seg]
        if len(ts) < 2:
            continue
        tr, w, f = apply_calibration(cal, ts, df[list(gcols)].to_numpy(float)[seg],
                                     df[list(acols)].to_numpy(float)[seg])
        ok = (ts >= tr[0]) & (ts <= tr[-1])
        for out, x in ((out_w, w), (out_f, f), (out_m, mag[seg])):
            for i in range(out.shape[1]):
                out[seg, i] = np.where(ok, np.interp(ts, tr, x[:, i]), np.nan)
    res = df.copy()
    for i, a in enumerate(XYZ):
        res[f"gyro_{a}_rad_s"] = out_w[:, i]
        res[f"acc_{a}_m_s2"] = out_f[:, i]
    if has_mag:
        c = np.asarray(decompose(cal.kg)["rotation_imu_to_body"], dtype=float)
        res[list(MAG_COLUMNS)] = out_m @ c.T
    if gcols == IMU_GYRO:
        res = res.drop(columns=list(IMU_GYRO + IMU_ACC))
    keep = np.isfinite(out_w).all(axis=1)
    return res.loc[keep].reset_index(drop=True)


# ------------------------------------------------------------------------ verification
def _rms(x: Array) -> list[float]:
    return [float(v) for v in np.sqrt(np.mean(x**2, axis=0))]  # (A.19)


def _verify(cal: Calibration, d: dict[str, Array]) -> dict[str, Any]:
    _, w, f = apply_calibration(cal, d["t"], d["gyro"], d["acc"])
    gr, ar = cal.ranges["gyro_rad_s"], cal.ranges["acc_m_s2"]
    g_raw, g_cor = _rms(d["gyro"] - d["omega"]), _rms(w - d["omega"])
    a_raw, a_cor = _rms(d["acc"] - d["f"]), _rms(f - d["f"])
    return {
        "samples": len(d["t"]),
        "gyro_rad_s": {"raw": g_raw, "corrected": g_cor},
        "acc_m_s2": {"raw": a_raw, "corrected": a_cor},
        "gyro_pct_range": {"raw": [100 * v / gr for v in g_raw],
                           "corrected": [100 * v / gr for v in g_cor]},
        "acc_pct_range": {"raw": [100 * v / ar for v in a_raw],
                          "corrected": [100 * v / ar for v in a_cor]},
        "gyro_pct_peak": [100 * v / float(np.abs(d["omega"]).max()) for v in g_cor],
        "acc_pct_peak": [100 * v / float(np.abs(d["f"] - d["f"].mean(0)).max()) for v in a_cor],
        "table_a2": {k: list(v) for k, v in TABLE_A2.items()},
    }


# -------------------------------------------------------------------------- pipeline
def calibrate(
    df: pd.DataFrame,
    measured_mounting_deg: tuple[float, float, float] | None = None,
    gyro_range_rad_s: float = ADIS16400_GYRO_RANGE_RAD_S,
    acc_range_m_s2: float = ADIS16400_ACC_RANGE_M_S2,
    max_lag_s: float = 0.5,
    warn_condition: float = 3.0,
    max_condition: float = 10.0,
    iterations: int = 3,
    time_offset_s: float | None = None,
) -> Calibration:
    """Run every stage of Paper A on a validated calibration log (see ``imu_log``).

    ``time_offset_s`` fixes the hexapod→IMU lag instead of estimating it (e.g. 0.0 to see
    what ignoring it costs, as the thesis did).
    """
    notes: list[str] = []
    hold = df.loc[df["phase"] == "bias", list(IMU_GYRO)].to_numpy(float)
    bias = hold.mean(axis=0)  # (A.12)
    stderr = hold.std(axis=0, ddof=1) / math.sqrt(len(hold))

    gmask = (df["phase"] == "gyro").to_numpy()
    gblk = max(_blocks(gmask), key=lambda s: s.stop - s.start)
    if time_offset_s is None:
        offset = estimate_time_offset(
            df["t_s"].to_numpy()[gblk], df[list(REF_OMEGA)].to_numpy()[gblk],
            df[list(IMU_GYRO)].to_numpy()[gblk], bias, max_lag_s)
    else:
        offset = float(time_offset_s)

    labels = ("gyro", "acc", "lever_x", "lever_y", "lever_z")
    ph = {lab: aligned_phase(df, lab, offset) for lab in labels}

    g = ph["gyro"]
    cond_g = excitation_condition(g["omega"], centred=False)
    _check_condition("gyro", cond_g, warn_condition, max_condition, notes)
    f_g, _ = fit_forward(g["omega"], g["gyro"] - bias, intercept=False)  # (A.7)-(A.9)
    k_gyro = np.asarray(np.linalg.inv(f_g), dtype=np.float64)

    a = ph["acc"]
    cond_a = excitation_condition(a["f"], centred=True)
    _check_condition("accelerometer", cond_a, warn_condition, max_condition, notes)
    r = np.zeros(3)
    lever: dict[str, Any] = {}
    acc_bias, k_acc = np.zeros(3), np.eye(3)  # replaced by the first pass (there is one)
    for _ in range(max(1, iterations)):
        f_imu = a["f"] + np.cross(a["alpha"], r) + np.cross(a["omega"], np.cross(a["omega"], r))
        f_a, acc_bias = fit_forward(f_imu, a["acc"], intercept=True)
        k_acc = np.asarray(np.linalg.inv(f_a), dtype=np.float64)
        lever = _lever_arm(ph, k_acc, acc_bias)
        r = lever["r"]

    cal = Calibration(
        gyro_bias_rad_s=bias.tolist(),
        gyro_bias_stderr_rad_s=stderr.tolist(),
        acc_bias_m_s2=[float(v) for v in acc_bias],
        k_gyro=k_gyro.tolist(),
        k_acc=k_acc.tolist(),
        lever_arm_m=r.tolist(),
        time_offset_s=offset,
        lever_arm_estimates={
            "table_a1_alpha_m": lever["alpha"],
            "omega2_m": lever["omega2"],
            "agreement_m": lever["agreement"].tolist(),
        },
        decomposition={
            "convention": DECOMPOSITION_CONVENTION,
            "gyro": decompose(k_gyro, measured_mounting_deg),
            "acc": decompose(k_acc, measured_mounting_deg),
        },
        conditioning={"gyro": cond_g, "acc": cond_a},
        ranges={"gyro_rad_s": gyro_range_rad_s, "acc_m_s2": acc_range_m_s2},
        warnings=notes,
        source=str(df.attrs.get("path", "")),
    )
    if bool((df["phase"] == "verify").any()):
        cal.verification_rms = _verify(cal, aligned_phase(df, "verify", offset))
    return cal


# ------------------------------------------------------------------------------ files
def save_calibration(cal: Calibration, path: str | Path) -> Path:
    """Write the calibration JSON atomically (temp file in the same folder, then rename)."""
    path = Path(path)
    text = json.dumps(cal.to_dict(), indent=2, ensure_ascii=False) + "\n"
    return write_atomically(path, lambda tmp: tmp.write_text(text, encoding="utf-8"))


def _field(data: dict[str, Any], path: Path, name: str, shape: tuple[int, ...]) -> Any:
    if name not in data:
        raise LogError(f"{path}: field {name}: missing")
    try:
        arr = np.asarray(data[name], dtype=float)
    except (TypeError, ValueError) as exc:
        raise LogError(f"{path}: field {name}: expected numbers, got {data[name]!r}") from exc
    if arr.shape != shape or not np.isfinite(arr).all():
        raise LogError(f"{path}: field {name}: expected finite numbers of shape {shape}, "
                       f"got {data[name]!r}")
    return arr.tolist() if shape else float(arr)


def load_calibration(path: str | Path) -> Calibration:
    """Read and check a calibration JSON written by :func:`save_calibration`."""
    path = Path(path)
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError as exc:
        raise LogError(f"{path}: file not found") from exc
    except (OSError, ValueError) as exc:
        raise LogError(f"{path}: not a readable JSON file: {exc}") from exc
    if not isinstance(data, dict):
        raise LogError(f"{path}: expected a JSON object at the top level")
    vec = (3,)
    return Calibration(
        gyro_bias_rad_s=_field(data, path, "gyro_bias_rad_s", vec),
        gyro_bias_stderr_rad_s=data.get("gyro_bias_stderr_rad_s", [0.0, 0.0, 0.0]),
        acc_bias_m_s2=_field(data, path, "acc_bias_m_s2", vec) if "acc_bias_m_s2" in data
        else [0.0, 0.0, 0.0],
        k_gyro=_field(data, path, "k_gyro", (3, 3)),
        k_acc=_field(data, path, "k_acc", (3, 3)),
        lever_arm_m=_field(data, path, "lever_arm_m", vec),
        time_offset_s=_field(data, path, "time_offset_s", ()),
        verification_rms=data.get("verification_rms"),
        lever_arm_estimates=data.get("lever_arm_estimates", {}),
        decomposition=data.get("decomposition", {}),
        conditioning=data.get("conditioning", {}),
        warnings=list(data.get("warnings", [])),
        source=str(data.get("source", "")),
    )
