"""Static curves of an actuator (Paper C section 4.4) and motor constants from parameters.

The thesis found thrust against speed (Fig. C.13) and current against speed (Fig. C.14)
by increasing the speed slowly and fitting polynomials; the inverse (thrust -> speed) turns
a thrust setpoint into a speed setpoint. Here the samples are first reduced to medians in
narrow speed bins (so a 25 kHz sweep, a 50 Hz stand log with sparse load-cell rows and a
log of hand-set plateaus all give a clean point cloud), then fitted by least squares:

* thrust = a w^2 + b w + c and its analytic inverse, and the pure k_f w^2 of (E.1) (the
  Gazebo motor constant) with the spread of the k_f one speed level gives; the residual
  is reported on the raw samples (``thrust_rms``: what a prediction of one sample is off
  by) and on the binned medians the curve was fitted to (``thrust_rms_binned``, much
  smaller: the medians have averaged the noise);
* current = polynomial in w (degree 3: power grows with w^3), whose slope at hover is
  the damping D of Fig. C.5;
* torque = k_q w^2 and torque / thrust (the moment constant), when torque is logged;
* steady command -> speed/thrust curves when the log has a command column.

``motor_constants`` gives K_E = K_T from K_V (2.37); ``from_parameters`` the mechanical time
constant and gain of (C.3) and (C.4), the "From Parameters" row of Table C.1.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.polynomial import Polynomial

from analysis.errors import LogError
from analysis.run_record import RunRecord

__all__ = [
    "TABLE_C2",
    "MotorParams",
    "StaticCurves",
    "binned_medians",
    "command_curve",
    "fit_static",
    "fit_static_run",
    "from_parameters",
    "lsq_through_origin",
    "motor_constants",
    "replicate_u",
]

RPM_TO_RAD_S = 2.0 * math.pi / 60.0


@dataclass(frozen=True)
class MotorParams:
    """Motor and rotor data of Table C.2 form (SI units; K_V in rpm/V as on datasheets)."""

    kv_rpm_v: float
    r_ohm: float
    j_kg_m2: float
    l_h: float = 0.0
    d_a_s_rad: float = math.nan  # damping D (A per rad/s), from the current curve


# Paper C's DJI 2212/920 kV motor with the 8x4.5 in propeller: measured and datasheet
# inputs of Table C.2 (not fitted results).
TABLE_C2 = MotorParams(kv_rpm_v=920.0, r_ohm=0.22, j_kg_m2=17.2e-6, l_h=80e-6, d_a_s_rad=0.004)


def motor_constants(kv_rpm_v: float) -> tuple[float, float]:
    """K_E (V s/rad) and K_T (N m/A) from K_V in rpm/V; K_T = K_E in SI units."""
    if not kv_rpm_v > 0:
        raise ValueError(f"K_V must be > 0 rpm/V, got {kv_rpm_v}")
    # (2.37) converts K_V from rpm/V to SI; the thesis prints the factor as 2 pi / 60 next
    # to 1 / K_V, but its own numbers (K_V 920 rpm/V -> K_E 0.0104 V s/rad, Table C.2)
    # need 1 rpm = 2 pi / 60 rad/s applied to the rpm in the denominator:
    ke = 1.0 / (kv_rpm_v * 2.0 * math.pi / 60.0)  # (2.37)
    return ke, ke


def from_parameters(p: MotorParams, d_a_s_rad: float | None = None) -> tuple[float, float]:
    """Mechanical time constant (s) and gain of the first-order model from parameters."""
    d = p.d_a_s_rad if d_a_s_rad is None else d_a_s_rad
    if not math.isfinite(d):
        raise ValueError("the damping D is unknown: give it or fit a current curve")
    ke, kt = motor_constants(p.kv_rpm_v)
    tau = p.j_kg_m2 * p.r_ohm / (p.r_ohm * kt * d + kt * ke)  # (C.3)
    gain = ke / (p.r_ohm * d + ke)  # (C.4)
    return tau, gain


def binned_medians(x: np.ndarray, ys: dict[str, np.ndarray], bins: int = 60,
                   min_count: int = 3, min_frac: float = 0.2,
                   trends: Mapping[str, Callable[[np.ndarray], np.ndarray]] | None = None
                   ) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """Median of x and of each y in ``bins`` equal-width bins of x (NaNs ignored per y).

    Bins holding fewer than ``min_frac`` of the median count of the occupied bins are
    dropped: in a log of held levels they are the transitions between the plateaus
    (acceleration currents, lagging thrust), in a slow sweep every bin is alike.

    A y with a ``trends`` curve is taken about it: the median of y - trend(x) sample by
    sample, plus the trend at the bin's median x. The plain median of y is not paired
    with the median of x (the middle of a staircase of speeds against the middle of
    noisy thrusts): over a curved y it was off by ~50 ppm of k_f, 0.3 of its standard
    uncertainty, and by more of the curve's linear and square coefficients."""
    trends = trends or {}
    ys = {name: np.asarray(y, float) - trends[name](np.asarray(x, float)) if name in trends
          else np.asarray(y, float) for name, y in ys.items()}
    x = np.asarray(x, float)
    ok = np.isfinite(x)
    lo, hi = (float(np.min(x[ok])), float(np.max(x[ok]))) if ok.any() else (0.0, 0.0)
    if not hi > lo:
        return np.empty(0), {k: np.empty(0) for k in ys}
    k = np.clip(((x - lo) / (hi - lo) * bins).astype(np.int64, copy=False), 0, bins - 1)
    k = np.where(ok, k, -1)
    xm, counts = _grouped_medians(k, x, bins)
    floor = max(min_count, min_frac * float(np.median(counts[counts > 0])))
    xm[counts < floor] = np.nan
    out = {}
    for name, y in ys.items():
        med, n = _grouped_medians(k, y, bins)
        out[name] = np.where(n >= min_count, med, np.nan)
    keep = np.isfinite(xm)
    for name, f in trends.items():
        if name in out:
            out[name][keep] += f(xm[keep])
    return xm[keep], {name: v[keep] for name, v in out.items()}


def _grouped_medians(k: np.ndarray, v: np.ndarray, groups: int
                     ) -> tuple[np.ndarray, np.ndarray]:
    """Median of the finite ``v`` of each group ``k`` (0 .. groups - 1; -1: none) and their
    counts, in one sort rather than a call of np.median per group (the same numbers: the
    middle value, or the mean of the two middle ones).

    The order by group, then value, is a sort of the values and then a stable one of
    their groups: with the groups as 16-bit integers numpy sorts those by radix, and the
    two took a fifth of ``np.lexsort``'s time on a sweep's 45 000 samples."""
    sel = (k >= 0) & np.isfinite(v)
    kk, vv = k[sel], v[sel]
    by_value = np.argsort(vv)
    if groups <= np.iinfo(np.int16).max:
        by_group = np.argsort(kk.astype(np.int16)[by_value], kind="stable")
    else:
        by_group = np.argsort(kk[by_value], kind="stable")
    order = by_value[by_group]
    kk, vv = kk[order], vv[order]
    counts = np.bincount(kk, minlength=groups)
    starts = np.cumsum(counts) - counts
    if vv.size == 0:
        return np.full(groups, np.nan), counts
    lo = np.minimum(starts + (counts - 1) // 2, vv.size - 1)
    hi = np.minimum(starts + counts // 2, vv.size - 1)
    return np.where(counts > 0, (vv[lo] + vv[hi]) / 2.0, np.nan), counts


@dataclass(frozen=True)
class StaticCurves:
    """Fitted static curves (speed w in rad/s, thrust in N, current in A, torque in N m)."""

    omega: np.ndarray = field(repr=False)  # binned points the fits used
    thrust: np.ndarray = field(repr=False)
    current: np.ndarray = field(repr=False)
    torque: np.ndarray = field(repr=False)
    thrust_poly: Polynomial | None  # thrust(w), degree 2 (Fig. C.13)
    current_poly: Polynomial | None  # current(w), degree 3 (Fig. C.14)
    k_f: float  # thrust = k_f w^2 (E.1), N s^2/rad^2
    k_q: float  # torque = k_q w^2 (E.2, E.3), N m s^2/rad^2
    moment_constant_m: float  # torque / thrust (m)
    thrust_rms: float  # residual of the raw samples (what a prediction is off by)
    current_rms: float
    thrust_rms_binned: float  # residual of the binned medians the curve was fitted to
    current_rms_binned: float
    omega_max: float  # highest steady speed in the data (rad/s)
    voltage_v: float  # median supply voltage (V)
    notes: tuple[str, ...] = ()  # what was done to the data (e.g. the thrust sign flipped)
    # spread of the k_f (k_q) one speed level gives (``lsq_through_origin``), NaN if unknown
    k_f_std: float = math.nan
    k_q_std: float = math.nan
    # how much k_f (k_q) moves per unit of zero error in every reading (the tare's)
    k_f_zero_sensitivity: float = math.nan
    k_q_zero_sensitivity: float = math.nan
    # standard uncertainty of k_f, k_q and the thrust polynomial's coefficients (ascending
    # powers of w) from the sweep's noise: ``replicate_u``; NaN where it could not be had
    k_f_u: float = math.nan
    k_q_u: float = math.nan
    thrust_poly_u: tuple[float, ...] = (math.nan, math.nan, math.nan)
    replicates: int = 0  # the sub-sweeps those came from (their degrees of freedom + 1)

    def thrust_at(self, omega: np.ndarray | float) -> np.ndarray:
        if self.thrust_poly is None:
            raise LogError("no thrust data: the thrust curve is unknown")
        return self.thrust_poly(np.asarray(omega, float))

    def omega_for_thrust(self, thrust_n: np.ndarray | float) -> np.ndarray:
        """Inverse of the thrust curve on its rising branch (Fig. C.6 f(F_Th, w))."""
        if self.thrust_poly is None:
            raise LogError("no thrust data: the thrust curve is unknown")
        c, b, a = ([*list(self.thrust_poly.convert().coef), 0.0, 0.0, 0.0])[:3]
        f = np.asarray(thrust_n, float)
        if abs(a) < 1e-15:
            return (f - c) / b
        disc = np.maximum(b * b - 4.0 * a * (c - f), 0.0)
        return (-b + np.sqrt(disc)) / (2.0 * a)

    def current_at(self, omega: np.ndarray | float) -> np.ndarray:
        if self.current_poly is None:
            raise LogError("no current data: the current curve is unknown")
        return self.current_poly(np.asarray(omega, float))

    def damping_at(self, omega: float) -> float:
        """dI/dw at a speed: the D of Fig. C.5 (A per rad/s)."""
        if self.current_poly is None:
            return math.nan
        return float(self.current_poly.deriv()(omega))

    def summary(self) -> dict[str, Any]:
        def coef(p: Polynomial | None) -> list[float] | None:
            return None if p is None else [float(c) for c in p.convert().coef]

        def num(x: float) -> float | None:
            return float(x) if math.isfinite(x) else None

        return {
            "thrust_poly_w": coef(self.thrust_poly),
            "current_poly_w": coef(self.current_poly),
            "k_f_n_s2": num(self.k_f),
            "k_q_nm_s2": num(self.k_q),
            "k_f_std_n_s2": num(self.k_f_std),
            "k_q_std_nm_s2": num(self.k_q_std),
            "moment_constant_m": num(self.moment_constant_m),
            "thrust_rms_n": num(self.thrust_rms),
            "current_rms_a": num(self.current_rms),
            "thrust_rms_binned_n": num(self.thrust_rms_binned),
            "current_rms_binned_a": num(self.current_rms_binned),
            "omega_max_rad_s": num(self.omega_max),
            "rpm_max": num(self.omega_max / RPM_TO_RAD_S),
            "voltage_v": num(self.voltage_v),
            "points": int(self.omega.size),
        }


REVERSED_THRUST_NOTE = ("thrust: the log's thrust falls as the rotor speeds up (load cell "
                        "mounted the other way, or a pusher propeller): its sign is flipped")


def thrust_sign(thrust_n: np.ndarray, drive: np.ndarray) -> float:
    """+1, or -1 when the thrust falls as ``drive`` (speed or command) rises: the median
    thrust of the top fifth of the drive below that of the bottom fifth. A stand's sign
    convention is its mounting's; k_f (E.1) and the thrust curves are for lift > 0."""
    f, x = np.asarray(thrust_n, float), np.asarray(drive, float)
    ok = np.isfinite(f) & np.isfinite(x)
    if ok.sum() < 4:
        return 1.0
    f, x = f[ok], x[ok]
    lo, hi = np.quantile(x, [0.2, 0.8])
    if not hi > lo:
        return 1.0
    return -1.0 if np.median(f[x >= hi]) < np.median(f[x <= lo]) else 1.0


def lsq_through_origin(x: np.ndarray, y: np.ndarray) -> tuple[float, float]:
    """Slope k of y = k x by least squares, and the spread of the k one point gives.

    The spread is that of one point as the fit weights them (by x^2): the residual RMS
    over the RMS of x, sqrt(sum(r^2) / (n - 1)) / sqrt(sum(x^2) / n) = sqrt(n) times the
    slope's standard error. For k_f (x = w^2) a point is one speed level (a bin of the
    sweep), as one edge is for a step fit's spread: what one measurement may show, not
    how well the mean is known. NaN with fewer than two points."""
    ok = np.isfinite(x) & np.isfinite(y)
    xs, ys = x[ok], y[ok]
    den = float(np.sum(xs**2))
    if not den > 0:
        return math.nan, math.nan
    k = float(np.sum(xs * ys) / den)
    n = xs.size
    if n < 2:
        return k, math.nan
    resid = ys - k * xs
    return k, float(np.sqrt(np.sum(resid**2) / (n - 1) / (den / n)))


def fit_static(
    rpm: np.ndarray,
    thrust_n: np.ndarray | None = None,
    current_a: np.ndarray | None = None,
    torque_nm: np.ndarray | None = None,
    voltage_v: np.ndarray | None = None,
    *,
    bins: int = 60,
    min_rpm: float | None = None,
    source: str = "log",
) -> StaticCurves:
    """Fit the static curves from samples (NaN where a sensor had no value)."""
    rpm = np.asarray(rpm, float)
    n = rpm.size
    nan = np.full(n, np.nan)
    th = nan if thrust_n is None else np.asarray(thrust_n, float)
    cu = nan if current_a is None else np.asarray(current_a, float)
    tq = nan if torque_nm is None else np.asarray(torque_nm, float)
    vv = nan if voltage_v is None else np.asarray(voltage_v, float)
    spinning = np.isfinite(rpm) & (rpm > 0)
    if not spinning.any():
        raise LogError(f"{source}: the rotor never turns (no rpm > 0): no static curve")
    notes: tuple[str, ...] = ()
    if thrust_sign(th, rpm) < 0:
        th, notes = -th, (REVERSED_THRUST_NOTE,)
    floor = 0.1 * float(np.max(rpm[spinning])) if min_rpm is None else min_rpm
    use = spinning & (rpm >= floor)
    w_raw = rpm[use] * RPM_TO_RAD_S
    raw = {"thrust": th[use], "current": cu[use], "torque": tq[use]}
    w, pts = binned_medians(w_raw, raw, bins=bins)
    if w.size < 4:
        raise LogError(f"{source}: only {w.size} speed levels with data; need >= 4 for a curve")
    trends = _trends(w, pts)  # a first pass's curves, to pair each sample's y with its w
    w, pts = binned_medians(w_raw, raw, bins=bins, trends=trends)

    def poly(y: np.ndarray, raw: np.ndarray, deg: int
             ) -> tuple[Polynomial | None, float, float]:
        """Fit on the binned medians; RMS of the raw samples and of the medians."""
        ok = np.isfinite(y)
        if ok.sum() < deg + 2:
            return None, math.nan, math.nan
        p = Polynomial.fit(w[ok], y[ok], deg)
        binned = float(np.sqrt(np.mean((p(w[ok]) - y[ok]) ** 2)))
        r = np.isfinite(raw)  # the medians came from these samples: never empty here
        raw_rms = float(np.sqrt(np.mean((p(w_raw[r]) - raw[r]) ** 2))) if r.any() else math.nan
        return p, raw_rms, binned

    tp, trms, trms_b = poly(pts["thrust"], th[use], 2)
    rep = replicate_u(w_raw, {"thrust": th[use], "torque": tq[use]}, bins, trends=trends)
    cp, crms, crms_b = poly(pts["current"], cu[use], 3)
    k_f, k_f_std = lsq_through_origin(w**2, pts["thrust"])
    k_q, k_q_std = lsq_through_origin(w**2, pts["torque"])
    vmed = float(np.nanmedian(vv[use])) if np.isfinite(vv[use]).any() else math.nan
    return StaticCurves(
        omega=w, thrust=pts["thrust"], current=pts["current"], torque=pts["torque"],
        thrust_poly=tp, current_poly=cp, k_f=k_f, k_q=k_q,
        moment_constant_m=k_q / k_f if math.isfinite(k_q) and k_f > 0 else math.nan,
        thrust_rms=trms, current_rms=crms, thrust_rms_binned=trms_b,
        current_rms_binned=crms_b, omega_max=float(np.max(w)), voltage_v=vmed, notes=notes,
        k_f_std=k_f_std, k_q_std=k_q_std,
        k_f_zero_sensitivity=_zero_sensitivity(w**2, pts["thrust"]),
        k_q_zero_sensitivity=_zero_sensitivity(w**2, pts["torque"]),
        k_f_u=rep.get("thrust", _NO_U)[0], k_q_u=rep.get("torque", _NO_U)[0],
        thrust_poly_u=rep.get("thrust", _NO_U)[1:], replicates=REPLICATES if rep else 0,
    )


_NO_U = (math.nan,) * 4
#: Interleaved sub-sweeps the noise of k_f, k_q and the thrust curve is read from.
REPLICATES = 10
#: Blocks of each sub-sweep per speed bin, on average: enough that every sub-sweep
#: covers every bin, few enough that a block outlasts the noise's correlation.
_BLOCKS_PER_BIN = 8


def replicate_u(w: np.ndarray, ys: dict[str, np.ndarray], bins: int,
                replicates: int = REPLICATES,
                trends: Mapping[str, Callable[[np.ndarray], np.ndarray]] | None = None
                ) -> dict[str, tuple[float, ...]]:
    """Standard uncertainties, from the samples' noise, of the slope through the origin
    (k of y = k w^2) and of the quadratic's coefficients (ascending powers) of each of
    ``ys`` against speed ``w`` (rad/s; samples in time order): ``(u_k, u_c0, u_c1, u_c2)``
    per name, from ``replicates`` interpenetrating sub-sweeps; no entry for a name that
    some sub-sweep has too few levels of.

    Why: the binned medians' scatter about the curve is mostly not noise. The median speed
    and the median thrust of a bin are not a pair (the middle of a staircase of speeds
    against the middle of noisy thrusts), and that mismatch alternates from bin to bin as
    the bins fall on the speed's steps: a scatter the slope hardly feels, so the levels'
    least-squares covariance overstated k_f's noise about threefold. Here the samples are
    dealt, in short blocks, into sub-sweeps that each span the whole range; the same fit
    of each gives ``replicates`` independent estimates, and the experimental standard
    deviation of their mean (GUM 4.2.3, nu = replicates - 1) is the noise of the estimate
    from all the samples (for medians, asymptotically). Blocks rather than single samples
    keep noise correlated over less than a block inside one sub-sweep."""
    per_bin = int(np.isfinite(w).sum()) // max(bins, 1)
    run = max(1, per_bin // (replicates * _BLOCKS_PER_BIN))
    group = (np.arange(w.size) // run) % replicates
    est: dict[str, list[tuple[float, ...]]] = {k: [] for k in ys}
    for g in range(replicates):
        sel = group == g
        wg, pts = binned_medians(w[sel], {k: v[sel] for k, v in ys.items()}, bins=bins,
                                 trends={k: f for k, f in (trends or {}).items() if k in ys})
        for name, y in pts.items():
            good = np.isfinite(y)
            if good.sum() < 4:
                est[name].append((math.nan,) * 4)
                continue
            x, yy = wg[good], y[good]
            c2, c1, c0 = np.polyfit(x, yy, 2)
            est[name].append((float(np.sum(x**2 * yy) / np.sum(x**4)),
                              float(c0), float(c1), float(c2)))
    out: dict[str, tuple[float, ...]] = {}
    for name, rows in est.items():
        a = np.array(rows)
        if a.shape[0] == replicates and np.isfinite(a).all():
            u = np.std(a, axis=0, ddof=1) / math.sqrt(replicates)
            out[name] = tuple(float(v) for v in u)
    return out


def _trends(w: np.ndarray, pts: dict[str, np.ndarray]
            ) -> dict[str, Callable[[np.ndarray], np.ndarray]]:
    """The curves of a first pass over the binned medians (the thrust's quadratic, the
    current's cubic, the torque's k_q w^2), for ``binned_medians``' trends."""
    out: dict[str, Callable[[np.ndarray], np.ndarray]] = {}
    for name, deg in (("thrust", 2), ("current", 3)):
        ok = np.isfinite(pts[name])
        if ok.sum() >= deg + 2:
            out[name] = Polynomial.fit(w[ok], pts[name][ok], deg)
    k_q = lsq_through_origin(w**2, pts["torque"])[0]
    if math.isfinite(k_q):
        out["torque"] = lambda x: k_q * x * x
    return out


def _zero_sensitivity(x: np.ndarray, y: np.ndarray) -> float:
    """dk/dc of the slope through the origin for a zero error c of every reading:
    sum(x) / sum(x^2) over the points fitted."""
    ok = np.isfinite(x) & np.isfinite(y)
    den = float(np.sum(x[ok] ** 2))
    return float(np.sum(x[ok]) / den) if den > 0 else math.nan


def fit_static_run(record: RunRecord, bins: int = 60) -> StaticCurves:
    """Static curves of a run folder (sweep, imported stand log, ...)."""
    cols = record.samples.columns

    def col(name: str) -> np.ndarray | None:
        return record.column(name) if name in cols else None

    if "rpm" not in cols:
        raise LogError(f"{record.path}: no 'rpm' column: static curves are against speed")
    thrust = col("thrust_n")
    if thrust is not None and not np.isfinite(thrust).any():
        thrust = None
    return fit_static(record.column("rpm"), thrust, col("current_a"), col("torque_nm"),
                      col("voltage_v"), bins=bins, source=str(record.path))


def command_curve(command: np.ndarray, value: np.ndarray, bins: int = 40
                  ) -> tuple[np.ndarray, np.ndarray]:
    """Steady value against command: medians per command bin (plateaus or a slow ramp)."""
    c, v = binned_medians(command, {"v": value}, bins=bins)
    ok = np.isfinite(v["v"])
    return c[ok], v["v"][ok]
