"""Model validation as in Paper C section 5: simulate fitted models on the Step 2 input.

Two models are driven by a run's thrust setpoint (delayed by the fitted latency) and
compared with the measured thrust:

* 5.1, the delay + first-order model of Table C.1, with the "switching mechanism" the
  thesis mentions: the rising time constant while the output climbs towards the setpoint,
  the falling one while it descends. Between setpoint changes the solution is an exact
  exponential, so the simulation is one vectorised update per setpoint segment.
* 5.2, the model with nonlinear load: Fig. C.5 with the constant D replaced by the
  measured load current f(w) (Fig. C.14), the thrust from the speed through the measured
  thrust curve (Fig. C.13), the voltage set so the steady speed is the setpoint's
  (Fig. C.6): J dw/dt = K_T [K_E (w_sp - w) + R_a (f(w_sp) - f(w))] / R_a (C.1 with
  L_a = 0). The stand measures supply current; the winding current the torque needs
  follows from the power balance i_bus V = K_E w i + R_a i^2.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy.integrate import solve_ivp

from analysis.errors import LogError
from analysis.run_record import RunRecord
from analysis.static_curves import MotorParams, StaticCurves, motor_constants
from analysis.step_response import StepResponse

__all__ = ["Validation", "simulate_first_order", "simulate_nonlinear_load", "validate_run"]


def _segments(t: np.ndarray, sp: np.ndarray, latency: float) -> tuple[np.ndarray, np.ndarray]:
    """Start times (delayed) and values of the piecewise-constant setpoint."""
    change = np.concatenate(([0], np.flatnonzero(np.diff(sp) != 0) + 1))
    return t[change] + latency, sp[change]


def simulate_first_order(t: np.ndarray, setpoint: np.ndarray, latency: float, tau_up: float,
                         tau_dn: float, gain: float = 1.0, y0: float | None = None
                         ) -> np.ndarray:
    """Delay + first-order lag with separate rising/falling time constants (C.2)."""
    t = np.asarray(t, float)
    sp = np.asarray(setpoint, float)
    starts, values = _segments(t, sp, latency)
    y = np.empty_like(t)
    level = gain * values[0] if y0 is None else y0
    first = t < starts[0]
    y[first] = level
    bounds = np.searchsorted(t, starts)
    for k, (s, v) in enumerate(zip(starts, values, strict=True)):
        i0 = bounds[k]
        i1 = bounds[k + 1] if k + 1 < len(bounds) else t.size
        target = gain * v
        tau = tau_up if target > level else tau_dn
        seg = t[i0:i1]
        y[i0:i1] = target + (level - target) * np.exp(-(seg - s) / tau)
        end = starts[k + 1] if k + 1 < len(starts) else s
        level = target + (level - target) * math.exp(-(end - s) / tau)
    return y


def _winding_current(i_bus: np.ndarray, omega: np.ndarray, v: float, ke: float, r: float
                     ) -> np.ndarray:
    """Winding current from supply current by the power balance i_bus V = K_E w i + R i^2."""
    emf = ke * omega
    return (-emf + np.sqrt(emf * emf + 4.0 * r * v * np.maximum(i_bus, 0.0))) / (2.0 * r)


def simulate_nonlinear_load(t: np.ndarray, setpoint: np.ndarray, latency: float,
                            static: StaticCurves, motor: MotorParams, supply_v: float,
                            omega0: float | None = None) -> np.ndarray:
    """Thrust of the model with nonlinear load (section 5.2) for a thrust setpoint."""
    if static.current_poly is None or static.thrust_poly is None:
        raise LogError("the nonlinear-load model needs thrust and current curves (a sweep)")
    ke, kt = motor_constants(motor.kv_rpm_v)
    r, j = motor.r_ohm, motor.j_kg_m2

    def load(w: np.ndarray | float) -> np.ndarray:
        return _winding_current(np.asarray(static.current_at(w)), np.asarray(w, float),
                                supply_v, ke, r)

    t = np.asarray(t, float)
    starts, values = _segments(t, np.asarray(setpoint, float), latency)
    w_sp_all = static.omega_for_thrust(values)
    f_sp_all = load(w_sp_all)
    omega = np.empty_like(t)
    w = float(w_sp_all[0] if omega0 is None else omega0)
    omega[t < starts[0]] = w
    bounds = np.searchsorted(t, starts)
    for k in range(len(starts)):
        i0 = bounds[k]
        i1 = bounds[k + 1] if k + 1 < len(bounds) else t.size
        t_end = starts[k + 1] if k + 1 < len(starts) else (t[-1] if t.size else starts[k])
        if t_end <= starts[k]:
            continue
        w_sp, f_sp = float(w_sp_all[k]), float(f_sp_all[k])

        def rhs(_t: float, y: np.ndarray, w_sp: float = w_sp, f_sp: float = f_sp
                ) -> np.ndarray:
            return kt * (ke * (w_sp - y) + r * (f_sp - load(y))) / (j * r)  # (C.2), 5.2

        sol = solve_ivp(rhs, (starts[k], t_end), [w], dense_output=True, rtol=1e-6,
                        atol=1e-3, max_step=0.005)
        if i1 > i0:
            omega[i0:i1] = sol.sol(t[i0:i1])[0]
        w = float(sol.y[0, -1])
    return static.thrust_at(omega)


@dataclass(frozen=True)
class Validation:
    """Step 2 errors of the two models against the measured thrust (N)."""

    rms_first_order: float
    rms_nonlinear: float
    band_n: float  # high - low setpoint, to read the errors in percent
    t_s: np.ndarray = field(repr=False)  # time grid (1 ms bins)
    measured: np.ndarray = field(repr=False)
    first_order: np.ndarray = field(repr=False)
    nonlinear: np.ndarray = field(repr=False)
    rising_starts: np.ndarray = field(repr=False)
    falling_starts: np.ndarray = field(repr=False)

    @property
    def rms_first_order_pct(self) -> float:
        return 100.0 * self.rms_first_order / self.band_n

    @property
    def rms_nonlinear_pct(self) -> float:
        return 100.0 * self.rms_nonlinear / self.band_n


def _binned(t: np.ndarray, cols: list[np.ndarray], dt: float) -> tuple[np.ndarray, list]:
    k = ((t - t[0]) / dt).astype(np.int64)
    n = int(k[-1]) + 1
    cnt = np.bincount(k, minlength=n).astype(float)
    keep = cnt > 0
    tb = (np.bincount(k, t, minlength=n) / np.maximum(cnt, 1))[keep]
    out = []
    for c in cols:
        good = np.isfinite(c)
        s = np.bincount(k[good], c[good], minlength=n)
        m = np.bincount(k[good], minlength=n).astype(float)
        with np.errstate(invalid="ignore", divide="ignore"):
            out.append((s / m)[keep])
    return tb, out


def validate_run(record: RunRecord, fit: StepResponse, static: StaticCurves | None = None,
                 motor: MotorParams | None = None, bin_s: float = 0.001) -> Validation:
    """Simulate both models on the run's thrust setpoint (e.g. a Step 2 run) and compare
    with its measured thrust over the stretch where the setpoint is defined."""
    if fit.up is None or fit.down is None:
        raise LogError(f"{record.path}: validation needs rising and falling fits")
    t = record.column("t_s")
    sp = record.column("thrust_setpoint_n") if "thrust_setpoint_n" in record.samples else None
    if sp is None or not np.isfinite(sp).any():
        raise LogError(f"{record.path}: no thrust setpoint to drive the models")
    y = record.column("thrust_n")
    ok = np.flatnonzero(np.isfinite(sp))
    sel = slice(int(ok[0]), int(ok[-1]) + 1)
    t, sp, y = t[sel], sp[sel], y[sel]
    sp = np.where(np.isfinite(sp), sp, np.nan)
    sp = _ffill(sp)
    tb, (yb, spb) = _binned(t, [y, sp], bin_s)
    spb = _ffill(spb)
    lat = 0.5 * (fit.up.latency.value + fit.down.latency.value)
    gain = 0.5 * (fit.up.gain.value + fit.down.gain.value) if fit.gain_unit.endswith("/N") \
        else 1.0
    y0 = float(np.nanmean(yb[: max(1, int(0.01 / bin_s))]))
    fo = simulate_first_order(tb, spb, lat, fit.up.tau.value, fit.down.tau.value, gain, y0)
    if static is not None and motor is not None and static.current_poly is not None:
        v = static.voltage_v if math.isfinite(static.voltage_v) else float(
            np.nanmedian(record.column("voltage_v")))
        nl = simulate_nonlinear_load(tb, spb, lat, static, motor, v,
                                     float(static.omega_for_thrust(y0)))
    else:
        nl = np.full_like(tb, np.nan)

    def rms(sim: np.ndarray) -> float:
        d = (yb - sim)[np.isfinite(yb) & np.isfinite(sim)]
        return float(np.sqrt(np.mean(d * d))) if d.size else math.nan

    ev = record.events
    labels = ev["label"].astype(str) if not ev.empty and "label" in ev else None
    rising = ev.loc[labels.str.endswith("rising"), "t_s"].to_numpy(float) if labels is not None \
        else np.empty(0)
    falling = ev.loc[labels.str.endswith("falling"), "t_s"].to_numpy(float) \
        if labels is not None else np.empty(0)
    band = float(np.nanmax(sp) - np.nanmin(sp))
    return Validation(rms(fo), rms(nl), band, tb, yb, fo, nl, rising, falling)


def _ffill(x: np.ndarray) -> np.ndarray:
    idx = np.where(np.isfinite(x), np.arange(x.size), 0)
    np.maximum.accumulate(idx, out=idx)
    return x[idx]
