"""Autopilot parameters from measured static curves and step fits.

Formulas from section 5 of the project's notes ``reference/thrust-stands.md`` (not shipped;
the firmware and wiki sources are named below):

* ArduPilot (AP_Motors_Thrust_Linearization): the firmware inverts
  ``T = (1 - e) x + e x^2`` with ``x`` the command normalised over
  [MOT_SPIN_MIN, MOT_SPIN_MAX] of the PWM range and ``T`` the thrust normalised by the
  thrust at SPIN_MAX. ``MOT_THST_EXPO`` is fitted by least squares (the wiki method, linear
  in ``e``) and, as a cross-check, by the WebTool criterion (the ``e`` for which thrust is
  most linear in demand: minimum standard deviation of d thrust / d demand).
  ``MOT_SPIN_MIN`` is the command where thrust starts and ``MOT_SPIN_MAX`` where it
  saturates (the curve stays flat from there to the end of the data), each only when the
  data covers that point; ``MOT_THST_HOVER`` is the linearised demand at hover thrust,
  refused when above 1 (the vehicle cannot hover on these motors).
* PX4 (FunctionMotors): ``rel_thrust = f rel_signal^2 + (1 - f) rel_signal`` with both
  normalised over the experiment (PX4 tuning guide); ``THR_MDL_FAC = f`` in [0, 1].
* Gazebo / PX4 SITL multirotor motor model: thrust = motorConstant w^2, drag torque =
  -turningDirection momentConstant thrust, first-order rotor speed with timeConstantUp /
  timeConstantDown, maxRotVelocity (rad/s). momentConstant is a positive magnitude (the
  direction of spin is the plugin's per-motor ``turningDirection``, cw = 1, ccw = -1), so a
  stand whose torque reads negative for this rotation exports |torque / thrust| with a note.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from datetime import timedelta
from typing import Any

import numpy as np
import pandas as pd

from analysis.errors import LogError
from analysis.run_record import RunRecord
from analysis.static_curves import (
    REVERSED_THRUST_NOTE,
    RPM_TO_RAD_S,
    StaticCurves,
    command_curve,
    fit_static_run,
    thrust_sign,
)
from analysis.step_response import StepResponse

__all__ = [
    "GazeboFits",
    "ThrustCurve",
    "actuator_of",
    "ardupilot_params",
    "expo_least_squares",
    "expo_webtool",
    "export_params",
    "gazebo_fits",
    "gazebo_params",
    "px4_params",
    "thrust_curve_from_runs",
]

SPIN_MIN_DEFAULT = 0.15  # ArduPilot defaults, used when the data cannot support a value
SPIN_MAX_DEFAULT = 0.95


@dataclass(frozen=True)
class ThrustCurve:
    """Steady thrust against the actuator command as a fraction 0..1 of the output range
    (PWM: (pwm - min) / (max - min); duty: duty / 100), ascending in command."""

    actuator: np.ndarray
    thrust_n: np.ndarray
    source: str = ""
    notes: tuple[str, ...] = ()  # carried into the exports' notes

    def __post_init__(self) -> None:
        a = np.asarray(self.actuator, float)
        t = np.asarray(self.thrust_n, float)
        ok = np.isfinite(a) & np.isfinite(t)
        a, t = a[ok], t[ok]
        order = np.argsort(a, kind="stable")
        a, t = a[order], t[order]
        if a.size < 4 or not a[-1] > a[0]:
            raise LogError(f"{self.source or 'thrust curve'}: need >= 4 steady (command, thrust) "
                           f"points over a range of commands, got {a.size}")
        object.__setattr__(self, "actuator", a)
        object.__setattr__(self, "thrust_n", t)


def _observed_start(c: ThrustCurve, loud: float = 0.02, silent: float = 0.005
                    ) -> tuple[float, float] | None:
    """(last command with at most ``silent`` of the maximum thrust, first command with
    more than ``loud`` of it) if the data shows both, else None (start not observed)."""
    peak = np.max(c.thrust_n)
    above = np.flatnonzero(c.thrust_n > loud * peak)
    if above.size == 0 or above[0] == 0:
        return None
    quiet = np.flatnonzero(c.thrust_n[: above[0]] <= silent * peak)
    if quiet.size == 0:
        return None
    return float(c.actuator[int(quiet[-1])]), float(c.actuator[int(above[0])])


def _expo_and_spin_min(c: ThrustCurve, spin_max: float, lo: float, hi: float
                       ) -> tuple[float, float]:
    """Least squares over SPIN_MIN in [lo, hi] (1e-3 grid) and MOT_THST_EXPO: the model
    is zero thrust below SPIN_MIN and the expo curve from there to SPIN_MAX."""
    work = c.actuator <= spin_max
    a, t = c.actuator[work], c.thrust_n[work] / np.interp(spin_max, c.actuator, c.thrust_n)
    s = np.arange(lo, hi + 5e-4, 1e-3)[:, None]
    u = np.clip((a[None, :] - s) / (spin_max - s), 0.0, 1.0)
    g = u * u - u
    den = np.sum(g * g, axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        e = np.clip(np.where(den > 0, np.sum((t - u) * g, axis=1) / den, 0.0), -1.0, 1.0)
    sse = np.sum(((1 - e[:, None]) * u + e[:, None] * u * u - t) ** 2, axis=1)
    k = int(np.argmin(sse))
    return float(s[k, 0]), float(e[k])


def _saturation(c: ThrustCurve, ratio: float = 0.5, min_span: float = 0.04) -> float | None:
    """The command above the middle of the range from which the thrust curve really
    flattens, else None.

    A point qualifies when every slope from it to the end of the data stays below
    ``ratio`` of the steepest slope seen before it and the flat part spans at least
    ``min_span`` of the command range with >= 2 further points. One flat or noisy bin in a
    rising curve (a plateau's median, a load-cell outlier) is not saturation: the curve
    rises again after it."""
    a, t = c.actuator, c.thrust_n
    slope = np.diff(t) / np.diff(a)
    peak = np.maximum.accumulate(slope)
    mid = 0.5 * (a[0] + a[-1])
    # the largest slope from each point on to the end (suffix maximum)
    ahead = np.maximum.accumulate(slope[::-1])[::-1]
    flat = (a[:-1] >= mid) & (ahead < ratio * peak) & (a[-1] - a[:-1] >= min_span) \
        & (np.arange(slope.size) <= slope.size - 2)
    k = np.flatnonzero(flat)
    return float(a[int(k[0])]) if k.size else None


def expo_least_squares(u: np.ndarray, t: np.ndarray) -> float:
    """Least-squares ``e`` of ``t = (1 - e) u + e u^2`` (closed form: linear in e), clipped
    to ArduPilot's range [-1, 1]."""
    g = u * u - u
    den = float(np.sum(g * g))
    if den <= 0:
        raise LogError("MOT_THST_EXPO: the command points do not span the working range")
    return float(np.clip(np.sum((t - u) * g) / den, -1.0, 1.0))


def expo_webtool(c: ThrustCurve, spin_min: float, spin_max: float, step: float = 0.005
                 ) -> float:
    """ArduPilot WebTools ThrustExpo: the expo for which measured thrust is most linear in
    demand (minimum standard deviation of its gradient), for demands 0..1 step 0.001."""
    e = np.round(np.arange(-1.0, 1.0 + step / 2, step), 6)
    d = np.linspace(0.0, 1.0, 1001)
    ee = e[:, None]
    with np.errstate(invalid="ignore", divide="ignore"):
        x = np.where(np.abs(ee) < 1e-12, d[None, :],
                     ((ee - 1.0) + np.sqrt((1.0 - ee) ** 2 + 4.0 * ee * d[None, :])) / (2.0 * ee))
    x = np.clip(np.nan_to_num(x), 0.0, 1.0)
    act = spin_min + (spin_max - spin_min) * x  # thrust_to_actuator
    thrust = np.interp(act, c.actuator, c.thrust_n)
    grad = np.diff(thrust, axis=1) / np.diff(d)
    return float(e[int(np.argmin(np.std(grad, axis=1)))])


def ardupilot_params(c: ThrustCurve, hover_thrust_n: float | None = None) -> dict[str, Any]:
    """MOT_THST_EXPO, MOT_SPIN_MIN/MAX (where supported) and MOT_THST_HOVER (if the hover
    thrust per motor is given), with the fit residual and notes."""
    notes = list(c.notes)
    start = _observed_start(c)
    sat = _saturation(c)
    spin_max = sat if sat is not None else SPIN_MAX_DEFAULT
    if sat is None:
        if c.actuator[-1] < SPIN_MAX_DEFAULT:
            spin_max = float(c.actuator[-1])
            notes.append("MOT_SPIN_MAX: no saturation up to the highest command tested "
                         f"({spin_max:.3f}); the curve is normalised there, default kept")
        else:
            notes.append("MOT_SPIN_MAX: the thrust does not saturate in the data; default kept")
    if start is not None:
        # the start of thrust lies below the first loud command
        spin_min, expo = _expo_and_spin_min(c, spin_max, float(c.actuator[0]), start[1])
    else:
        notes.append("MOT_SPIN_MIN: the data does not show where thrust starts; default kept")
        spin_min = min(SPIN_MIN_DEFAULT, float(c.actuator[0]))
        expo = None
    if not spin_max > spin_min:
        raise LogError(f"{c.source}: SPIN_MAX {spin_max:.3f} is not above SPIN_MIN "
                       f"{spin_min:.3f}")
    t_max = float(np.interp(spin_max, c.actuator, c.thrust_n))
    work = (c.actuator >= spin_min) & (c.actuator <= spin_max)
    u = (c.actuator[work] - spin_min) / (spin_max - spin_min)
    t = c.thrust_n[work] / t_max
    if u.size < 3:
        raise LogError(f"{c.source}: fewer than 3 points between SPIN_MIN and SPIN_MAX")
    if expo is None:
        expo = expo_least_squares(u, t)
    resid = (1 - expo) * u + expo * u * u - t
    out: dict[str, Any] = {
        "MOT_THST_EXPO": round(expo, 3),
        "MOT_SPIN_MIN": round(spin_min, 3) if start is not None else None,
        "MOT_SPIN_MAX": round(spin_max, 3) if sat is not None else None,
        "expo_webtool": expo_webtool(c, spin_min, spin_max),
        "fit_rms": float(np.sqrt(np.mean(resid**2))),
        "thrust_at_spin_max_n": t_max,
        "points": int(u.size),
    }
    if hover_thrust_n is not None:
        demand = hover_thrust_n / t_max  # linearised demand: thrust / lift at SPIN_MAX
        if demand > 1.0:
            raise LogError(f"{c.source}: MOT_THST_HOVER: the vehicle cannot hover: it needs "
                           f"{hover_thrust_n:.3g} N per motor, the motor gives at most "
                           f"{t_max:.3g} N at SPIN_MAX ({spin_max:.3f}) in this data "
                           f"(demand {demand:.2f} > 1)")
        out["MOT_THST_HOVER"] = round(demand, 4)
        if not 0.125 <= demand <= 0.6875:
            notes.append(f"MOT_THST_HOVER {demand:.3f} is outside ArduPilot's range "
                         "0.125-0.6875: the motor is too weak or too strong for this weight")
    out["notes"] = notes
    return out


def px4_params(c: ThrustCurve) -> dict[str, Any]:
    """THR_MDL_FAC by least squares with both axes normalised over the experiment."""
    a, t = c.actuator, c.thrust_n
    s = (a - a.min()) / (a.max() - a.min())
    r = (t - t.min()) / (t.max() - t.min())
    g = s * s - s
    den = float(np.sum(g * g))
    f = float(np.clip(np.sum((r - s) * g) / den, 0.0, 1.0)) if den > 0 else 0.0
    resid = f * s * s + (1 - f) * s - r
    return {"THR_MDL_FAC": round(f, 3), "fit_rms": float(np.sqrt(np.mean(resid**2))),
            "points": int(a.size), "notes": list(c.notes)}


def gazebo_params(k_f: float, moment_constant_m: float, tau_up_s: float | None,
                  tau_down_s: float | None, omega_max: float, reaches_full_command: bool,
                  notes: tuple[str, ...] = ()) -> dict[str, Any]:
    """Parameters of the Gazebo multirotor motor model plugin (``notes``: the fit's own)."""
    remarks = list(notes)
    if not (math.isfinite(k_f) and k_f > 0):
        raise LogError("motorConstant: no thrust-vs-speed data")
    if not math.isfinite(moment_constant_m):
        remarks.append("momentConstant: no torque in the data")
    elif moment_constant_m < 0:
        remarks.append("momentConstant: the log's torque has the opposite sign to its thrust "
                     "(the stand's sign convention for this rotation); exported as the "
                     "magnitude, the spin direction is the model's turningDirection")
    # the plugin applies drag torque = -turningDirection * momentConstant * thrust, so
    # momentConstant is a positive magnitude; the rotor's direction is set per motor
    moment_constant_m = abs(moment_constant_m)
    if tau_up_s is None or tau_down_s is None:
        remarks.append("timeConstantUp/Down: give a step run (--step-run) to fit them")
    if not reaches_full_command:
        remarks.append("maxRotVelocity: the highest speed in the data, below full command")

    def num(x: float | None, nd: int = 6) -> float | None:
        return None if x is None or not math.isfinite(x) else float(f"{x:.{nd}g}")

    return {"motorConstant": num(k_f), "momentConstant": num(moment_constant_m),
            "timeConstantUp": num(tau_up_s, 4), "timeConstantDown": num(tau_down_s, 4),
            "maxRotVelocity": num(omega_max, 5), "notes": remarks}


# --- from run folders ---------------------------------------------------------------------


def actuator_of(record: RunRecord) -> tuple[np.ndarray, str]:
    """The command as a fraction of the output range: ``throttle_us`` over the ESC range
    in run.json (1000-2000 us if absent) or ``duty_pct`` / 100."""
    cols = record.samples.columns
    if "throttle_us" in cols and np.isfinite(record.column("throttle_us")).any():
        rig = record.meta.get("rig")
        esc = rig.get("esc", {}) if isinstance(rig, dict) else {}
        lo = float(esc.get("min_us", 1000.0)) if isinstance(esc, dict) else 1000.0
        hi = float(esc.get("max_us", 2000.0)) if isinstance(esc, dict) else 2000.0
        return (record.column("throttle_us") - lo) / (hi - lo), f"throttle_us over {lo:g}-{hi:g}"
    if "duty_pct" in cols and np.isfinite(record.column("duty_pct")).any():
        return record.column("duty_pct") / 100.0, "duty_pct / 100"
    raise LogError(f"{record.path}: no command column (throttle_us or duty_pct) for an "
                   "autopilot export")


#: A command is "steady" where it stayed within STEADY_SPREAD of the output range for
#: the last STEADY_WINDOW_S: three time constants of a slow rotor (0.1 s; Table C.1's run
#: from 30 to 80 ms), so a level held that long has settled to 95 % and a ramp that slow
#: (under 5 % of the range per 0.3 s) lags the command by under 2 % of the range.
STEADY_WINDOW_S = 0.3
STEADY_SPREAD = 0.05
#: The widest stretch of the commanded range that may hold no steady command (a 5 % duty
#: staircase leaves 5 %; a Step 1 run leaves idle to its low level, over 40 %).
MAX_UNCOVERED = 0.15


def check_static_coverage(record: RunRecord, act: np.ndarray) -> None:
    """Refuse a run whose steady commands do not cover its command range (LogError).

    A command-to-thrust curve is only the static curve where the thrust had time to
    follow the command: a sweep or a staircase. A step run holds two levels and moves
    between them (and from idle) in a second, so its binned medians are lagging
    transients: exporting them gave MOT_THST_EXPO 0.71 where the sweep of the same rig
    gives 0.385."""
    t = record.column("t_s")
    ok = np.isfinite(act) & np.isfinite(t)
    a, t = act[ok], t[ok] - t[ok][0] if ok.any() else t[ok]
    if a.size < 2:
        return  # ThrustCurve refuses too few points with its own message
    window = pd.Series(a, index=pd.to_timedelta(t, unit="s")).rolling(
        timedelta(seconds=STEADY_WINDOW_S))
    spread = np.asarray(window.max()) - np.asarray(window.min())
    steady = np.unique(a[(spread <= STEADY_SPREAD) & (t >= STEADY_WINDOW_S)])
    edges = np.concatenate([[a.min()], steady, [a.max()]])
    k = int(np.argmax(np.diff(edges)))
    gap = float(edges[k + 1] - edges[k])
    if gap > MAX_UNCOVERED:
        raise LogError(f"{record.path}: not a static sweep: its command never holds still "
                       f"(within {STEADY_SPREAD:.0%} of the range for {STEADY_WINDOW_S:g} s) "
                       f"between {edges[k]:.2f} and {edges[k + 1]:.2f} of the output range, "
                       f"so the thrust there is a transient; export from a slow sweep "
                       "(`rotorbench sweep`) or a stand log that steps the command slowly")


def thrust_curve_from_runs(record: RunRecord, thrust_record: RunRecord | None = None,
                           bins: int = 40) -> ThrustCurve:
    """Steady thrust per command level of ``record``; if that run has no thrust (e.g. an
    ESC telemetry log), the speed per command level goes through the thrust-vs-speed
    curve fitted on ``thrust_record`` (e.g. the stand log of the same test). ``record``
    must cover its command range slowly (:func:`check_static_coverage`)."""
    act, _ = actuator_of(record)
    check_static_coverage(record, act)
    cols = record.samples.columns
    if "thrust_n" in cols and np.isfinite(record.column("thrust_n")).any():
        thrust = record.column("thrust_n")
        notes: tuple[str, ...] = ()
        if thrust_sign(thrust, act) < 0:
            thrust, notes = -thrust, (REVERSED_THRUST_NOTE,)
        a, t = command_curve(act, thrust, bins=bins)
        return ThrustCurve(a, t, str(record.path), notes)
    if thrust_record is None:
        raise LogError(f"{record.path}: no thrust in this run; give a run with thrust against "
                       "speed of the same actuator (--thrust-run)")
    if "rpm" not in cols:
        raise LogError(f"{record.path}: neither thrust nor rpm to map commands to thrust")
    static = fit_static_run(thrust_record)
    a, rpm = command_curve(act, record.column("rpm"), bins=bins)
    w = rpm * RPM_TO_RAD_S
    t = np.where(rpm > 0, np.maximum(static.thrust_at(w), 0.0), 0.0)
    return ThrustCurve(a, t, f"{record.path} via {thrust_record.path}", static.notes)


@dataclass(frozen=True)
class GazeboFits:
    """The fits a Gazebo export reads, made once: its parameters and its uncertainty
    sidecar (``analysis.export_uncertainty``) come from the same two."""

    static: StaticCurves  #: of the thrust run (else the run itself)
    step: StepResponse | None  #: of the step run, on rpm, when one is given


def gazebo_fits(record: RunRecord, thrust_record: RunRecord | None = None,
                step_record: RunRecord | None = None) -> GazeboFits:
    from analysis.step_response import fit_run

    return GazeboFits(fit_static_run(thrust_record or record),
                      fit_run(step_record, signal="rpm") if step_record is not None else None)


def export_params(target: str, record: RunRecord, thrust_record: RunRecord | None = None,
                  step_record: RunRecord | None = None,
                  hover_thrust_n: float | None = None,
                  fits: GazeboFits | None = None) -> dict[str, Any]:
    """The parameters of one export target (``ardupilot``, ``px4``, ``gazebo``) from a
    run with static data: what ``rotorbench export`` and the web view's download give.
    ``fits``: the Gazebo fits when the caller made them already (``gazebo_fits``)."""
    if target in ("ardupilot", "px4"):
        curve = thrust_curve_from_runs(record, thrust_record)
        out = ardupilot_params(curve, hover_thrust_n) if target == "ardupilot" \
            else px4_params(curve)
        out["command_axis"] = actuator_of(record)[1]
    elif target == "gazebo":
        fits = fits or gazebo_fits(record, thrust_record, step_record)
        static, fit = fits.static, fits.step
        tau_up = fit.up.tau.value if fit is not None and fit.up else None
        tau_dn = fit.down.tau.value if fit is not None and fit.down else None
        omega_max = static.omega_max
        try:
            act = actuator_of(record)[0]
            full = bool(np.nanmax(act) >= 0.99)
            if "rpm" in record.samples.columns:  # steady top speed of the run itself
                _, rpm = command_curve(act, record.column("rpm"))
                omega_max = float(np.max(rpm)) * RPM_TO_RAD_S
        except LogError:  # no command column: the top speed is just the highest seen
            full = False
        out = gazebo_params(static.k_f, static.moment_constant_m, tau_up, tau_dn,
                            omega_max, full, static.notes)
    else:
        raise LogError(f"export target {target!r}: expected ardupilot, px4 or gazebo")
    out["target"] = target
    out["run"] = str(record.path)
    return out
