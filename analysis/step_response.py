"""Step-response identification: first-order-plus-delay per edge and on the mean of repeats.

Paper C (section 4.3, Table C.1) describes the actuator from thrust setpoint to thrust as a
delay and a first-order lag, fitted separately to rising and falling steps (Step 1, the
mean of 20 repeats), and compares the two directions by the RMS of their difference. Here:

* edges are found in the command column (``throttle_us``, else ``thrust_setpoint_n``) and
  timed by the run's ``step_start`` events when they fall within one sample of the jump;
* every edge window is averaged into short bins (default 0.5 ms, so 25 kHz data is cheap to
  fit and the load cell's ringing averages out); the bins of all edges form one matrix;
* each edge and the mean of the repeats of each direction get a least-squares fit of
  ``y0 + (y1 - y0) (1 - exp(-(t - L) / tau))`` for ``t > L`` (latency L, time constant tau,
  gain = (y1 - y0) / step of the setpoint); the initial guess is the two-point method
  ``tau = 1.5 (t63 - t28)``, ``L = t63 - tau``;
* the 63 % rise time is read from the data (first crossing of 63.2 % of the fitted
  change, measured from the command edge, so it includes the latency: ``L + tau`` when
  the model fits); a level held less than 4 tau gets a note (not settled);
* when the single edges' latencies scatter more than their fits' noise explains, by over
  ``ALIGN_TAUS`` of tau (a firmware whose output waits on its own task, a host that sent a
  command late), the repeats are averaged aligned at their own latencies: averaged at the
  command edge, a latency spread sigma widens the mean's lag to about sqrt(tau^2 +
  sigma^2) (a Betaflight ESC's five down edges each fitted 29.5-30.0 ms, their latencies
  5-46 ms, and the plain mean read 37.1 ms); the latency is then their mean;
* a repeat whose single fit's lag is off its repeats' median by more than a factor
  ``REPEAT_TAU_RATIO`` and by more than ``REPEAT_TAU_SIGMAS`` of its own fit's uncertainty
  is no response of the actuator the others show (a host stall bunched its samples, a
  dropout cut it) and is listed with why, not averaged (a wire rig's down edge fitted
  latency 0 and tau 6.2 ms beside two of 16 and 30 ms, and pulled the latency 5 ms early);
  never more than a minority of a group's edges, at least three fitted;
* the spread of the single-edge estimates gives each estimate's uncertainty (``Estimate``:
  ``std`` is the spread of one edge, ``stderr`` that of the mean of the repeats);
* a second-order fit with two real poles (the form of C.1) is available as an option.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import asdict, dataclass, field, replace
from typing import Any

import numpy as np
from scipy.optimize import least_squares

from analysis.cell_response import CellDynamics, thrust_step, thrust_step_jacobian
from analysis.errors import LogError
from analysis.run_record import RunRecord, esc_frame_s, event_times

__all__ = [
    "DirectionFit",
    "Edge",
    "Estimate",
    "FirstOrderFit",
    "SecondOrderFit",
    "StepResponse",
    "detect_edges",
    "first_order_step",
    "fit_run",
    "fit_step_response",
    "pooled_std",
    "second_order_step",
]

T63 = 1.0 - math.exp(-1.0)  # 0.632: the response of a first-order lag after one tau
T28 = 1.0 - math.exp(-1.0 / 3.0)  # 0.283: after tau / 3 (two-point method)
MIN_BINS = 6  # bins with samples an edge needs for a fit (4 parameters + 2)
MIN_SAMPLES_PER_TAU = 1.0  # a signal sampled more slowly than tau cannot resolve it
# A rising edge from a rotor at rest is the ESC's start-up routine (alignment, open-loop
# ramp: the ESC32 logs State 3 "starting"), not the first-order lag of a turning rotor that
# Table C.1 describes (a 0 -> 10 % duty start of the shipped F40 log reaches 63 % after
# 270 ms, its running steps after ~40 ms). Such an edge is listed, not fitted: at rest means
# every speed sample of the REST_WINDOW_S before the edge at most REST_FRACTION of the top.
REST_FRACTION = 0.01
REST_WINDOW_S = 0.1
#: the edges' latency scatter beyond their fits' noise, in time constants, above which the
#: repeats are averaged aligned at their own latencies (module doc): 0.1 tau widens the
#: plain mean's lag by 0.5 %
ALIGN_TAUS = 0.1
#: a repeat whose tau is off its repeats' median by more than this factor, and by more than
#: ``REPEAT_TAU_SIGMAS`` of its fit's uncertainty, is left out of the mean (module doc)
REPEAT_TAU_RATIO = 2.0
REPEAT_TAU_SIGMAS = 3.0
START_WHY = ("start from standstill (the ESC's start-up routine, not a first-order lag of "
             "a turning rotor)")


def finite_mean(values: Any) -> float:
    """Mean of the finite values, NaN if there are none (no "Mean of empty slice")."""
    v = np.asarray(values, float)
    v = v[np.isfinite(v)]
    return float(np.mean(v)) if v.size else math.nan


# --- models ---------------------------------------------------------------------------------


def first_order_step(t: np.ndarray, latency: float, tau: float) -> np.ndarray:
    """Unit step response of exp(-L s) / (tau s + 1) (the first-order model of C.2)."""
    s = np.clip(t - latency, 0.0, None)
    return -np.expm1(-s / tau)


def second_order_step(t: np.ndarray, latency: float, tau1: float, tau2: float) -> np.ndarray:
    """Unit step response of exp(-L s) / ((tau1 s + 1)(tau2 s + 1)), tau1 > tau2 (C.1 with
    real poles)."""
    s = np.clip(t - latency, 0.0, None)
    if abs(tau1 - tau2) < 1e-9 * tau1:
        return 1.0 - (1.0 + s / tau1) * np.exp(-s / tau1)
    return 1.0 - (tau1 * np.exp(-s / tau1) - tau2 * np.exp(-s / tau2)) / (tau1 - tau2)


# --- edges ----------------------------------------------------------------------------------


@dataclass(frozen=True)
class Edge:
    """A jump of the command: time, levels before/after and how long each level was held."""

    index: int  # first sample with the new command
    t_s: float
    u_before: float
    u_after: float
    setpoint_before: float
    setpoint_after: float
    hold_before_s: float
    hold_after_s: float

    @property
    def direction(self) -> str:
        return "up" if self.u_after > self.u_before else "down"

    @property
    def step(self) -> float:
        """Size of the step in setpoint units if known, else in command units."""
        if (math.isfinite(self.setpoint_before) and math.isfinite(self.setpoint_after)
                and self.setpoint_after != self.setpoint_before):
            return self.setpoint_after - self.setpoint_before
        return self.u_after - self.u_before  # no setpoint, or one that did not move


def detect_edges(
    t: np.ndarray,
    u: np.ndarray,
    setpoint: np.ndarray | None = None,
    event_t: np.ndarray | None = None,
    rel_jump: float = 0.05,
    min_level_s: float = 0.05,
) -> list[Edge]:
    """Jumps of the command ``u``: changes larger than ``rel_jump`` of its range, and
    smaller changes between levels held at least ``min_level_s`` each.

    Ramps (small increments every tick) are not edges but end the hold before and after
    an edge. The edge time is the matching event time if an event lies between the
    last old and the first new sample, else the midpoint of those two samples.
    """
    t = np.asarray(t, float)
    u = np.asarray(u, float)
    ok = np.isfinite(u)
    if ok.sum() < 2:
        return []
    t, u = t[ok], u[ok]
    sp = np.full(u.shape, np.nan) if setpoint is None else np.asarray(setpoint, float)[ok]
    du = np.diff(u)
    span = float(np.max(u) - np.min(u))
    if span <= 0:
        return []
    change = np.flatnonzero(du != 0.0) + 1  # first sample of every new command value
    # hold of the level before and after each change (until the neighbouring change)
    bounds = np.concatenate(([0], change, [u.size - 1]))
    before = t[change] - t[bounds[:-2]]
    after = t[bounds[2:]] - t[change]
    big = np.abs(du[change - 1]) > rel_jump * span
    held = (before >= min_level_s) & (after >= min_level_s)
    pick = np.flatnonzero(big | held)
    if pick.size == 0:
        return []
    jump = change[pick]
    prev_change = bounds[pick]
    next_change = bounds[pick + 2]
    t_prev, t_new = t[jump - 1], t[jump]
    t_edge = 0.5 * (t_prev + t_new)
    if event_t is not None and len(event_t):
        ev = np.asarray(event_t, float)
        k = np.searchsorted(ev, t_new, side="right") - 1
        valid = k >= 0
        ek = ev[np.clip(k, 0, None)]
        hit = valid & (ek > t_prev) & (ek <= t_new)
        t_edge = np.where(hit, ek, t_edge)
    edges = []
    for j, k in enumerate(jump):
        edges.append(Edge(
            index=int(k),
            t_s=float(t_edge[j]),
            u_before=float(u[k - 1]),
            u_after=float(u[k]),
            setpoint_before=float(sp[k - 1]),
            setpoint_after=float(sp[k]),
            hold_before_s=float(t_edge[j] - t[prev_change[j]]),
            hold_after_s=float(t[next_change[j]] - t_edge[j]),
        ))
    return edges


# --- fits -----------------------------------------------------------------------------------


@dataclass(frozen=True)
class FirstOrderFit:
    """Latency, time constant and gain of one response (single edge or mean of repeats)."""

    latency_s: float
    tau_s: float
    gain: float
    y0: float
    y1: float
    rms: float  # residual RMS in signal units
    t63_s: float  # 63.2 % rise time read from the data, from the command edge
    ok: bool = True
    why: str = ""  # why there is no estimate (ok False)
    # standard uncertainties from the fit's covariance (the residuals' scatter through the
    # Jacobian): what the noise of this one response puts into latency and tau
    u_latency_s: float = math.nan
    u_tau_s: float = math.nan
    # the fitted model's own 63.2 % crossing: latency + tau for a first-order response,
    # later for a square-law thrust and a cell's lag; what t63_s read from the data checks
    model_t63_s: float = math.nan

    @property
    def fitted(self) -> bool:
        """A usable estimate: the solver converged to finite latency and tau."""
        return self.ok and math.isfinite(self.tau_s) and math.isfinite(self.latency_s)


@dataclass(frozen=True)
class SecondOrderFit:
    """Latency and two real time constants (C.1 with L_a > 0), tau1 >= tau2."""

    latency_s: float
    tau1_s: float
    tau2_s: float
    gain: float
    y0: float
    y1: float
    rms: float


@dataclass(frozen=True)
class Estimate:
    """One number with its spread over repeats (std) and the standard error of the mean."""

    value: float
    std: float
    stderr: float
    n: int

    @staticmethod
    def of(mean_fit_value: float, singles: np.ndarray) -> Estimate:
        s = np.asarray(singles, float)
        s = s[np.isfinite(s)]
        std = float(np.std(s, ddof=1)) if s.size > 1 else math.nan
        return Estimate(float(mean_fit_value), std, std / math.sqrt(s.size) if s.size > 1
                        else math.nan, int(s.size))


def pooled_std(estimates: Any) -> float:
    """The spread of one edge over several groups of edges (e.g. the rising and the
    falling latency): sqrt(sum((n_i - 1) s_i^2) / sum(n_i - 1)) over the groups that have
    a spread, NaN if none has. Each group's own mean is taken out first, so a latency
    that differs between rising and falling edges is not counted as spread."""
    pairs = [(e.n - 1, e.std) for e in estimates if e.n > 1 and math.isfinite(e.std)]
    dof = sum(d for d, _ in pairs)
    return math.sqrt(sum(d * s * s for d, s in pairs) / dof) if dof else math.nan


@dataclass(frozen=True)
class DirectionFit:
    """Rising or falling edges of one level pair: the mean-of-repeats fit and the spread."""

    direction: str
    u_before: float
    u_after: float
    step: float
    edges: tuple[int, ...]
    mean: FirstOrderFit
    singles: tuple[FirstOrderFit, ...]
    latency: Estimate
    tau: Estimate
    gain: Estimate
    t63: Estimate
    t_s: np.ndarray = field(repr=False)  # bin times relative to the edge
    y_mean: np.ndarray = field(repr=False)  # mean response of the repeats
    second_order: SecondOrderFit | None = None
    pooled: bool = False  # values are means of single-edge fits at different levels
    aligned: bool = False  # the repeats averaged aligned at their own latencies

    @property
    def fitted_edges(self) -> tuple[int, ...]:
        """Indices (into ``StepResponse.edges``) of the edges with an estimate."""
        return tuple(i for i, f in zip(self.edges, self.singles, strict=True) if f.fitted)

    def describe(self) -> str:
        """Where the headline numbers of this direction come from."""
        n = len(self.fitted_edges)
        if self.pooled:
            return (f"mean of {n} single-edge fits at different levels (no level pair "
                    "repeated)")
        how = " aligned at their own latencies" if self.aligned else ""
        return (f"fit of the mean of {len(self.edges)} repeats{how} {self.u_before:g} -> "
                f"{self.u_after:g} ({n} single edges fitted)")


@dataclass(frozen=True)
class StepResponse:
    """Everything ``rotorbench fit`` reports for one run."""

    signal: str
    command: str
    gain_unit: str
    edges: tuple[Edge, ...]
    groups: tuple[DirectionFit, ...]
    up: DirectionFit | None
    down: DirectionFit | None
    rise_fall_rms: float  # Table C.1 RMS of |rising change| - |falling change|, 500 ms
    window_s: float
    bin_s: float
    notes: tuple[str, ...] = ()  # e.g. why another signal was not fitted
    excluded: tuple[tuple[int, str], ...] = ()  # (edge index, why) left out of the fits
    cell: CellDynamics | None = None  # the sensor mechanics the fit modelled
    square_law: bool = False  # thrust fitted as the square of a first-order speed

    def summary(self) -> dict[str, Any]:
        """The JSON of ``rotorbench fit`` (times in ms, signal units otherwise)."""

        def ms(x: float) -> float | None:
            return None if not math.isfinite(x) else round(x * 1e3, 4)

        def num(x: float) -> float | None:
            return None if not math.isfinite(x) else float(x)

        up, dn = self.up, self.down
        lat = [d.latency for d in (up, dn) if d is not None]
        out: dict[str, Any] = {
            "signal": self.signal,
            "command": self.command,
            "latency_ms": ms(float(np.mean([e.value for e in lat]))) if lat else None,
            "latency_up_ms": ms(up.latency.value) if up else None,
            "latency_down_ms": ms(dn.latency.value) if dn else None,
            "tau_up_ms": ms(up.tau.value) if up else None,
            "tau_down_ms": ms(dn.tau.value) if dn else None,
            "tau_up_std_ms": ms(up.tau.std) if up else None,
            "tau_down_std_ms": ms(dn.tau.std) if dn else None,
            "latency_std_ms": ms(pooled_std(lat)) if lat else None,
            "gain": num(float(np.mean([d.gain.value for d in (up, dn) if d is not None])))
            if (up or dn) else None,
            "gain_up": num(up.gain.value) if up else None,
            "gain_down": num(dn.gain.value) if dn else None,
            "gain_unit": self.gain_unit,
            "rise_fall_rms": num(self.rise_fall_rms),
            "rise_time_63_up_ms": ms(up.t63.value) if up else None,
            "rise_time_63_down_ms": ms(dn.t63.value) if dn else None,
            "model_rise_time_63_up_ms": ms(up.mean.model_t63_s) if up else None,
            "model_rise_time_63_down_ms": ms(dn.mean.model_t63_s) if dn else None,
            "repeats_up": up.tau.n if up else 0,
            "repeats_down": dn.tau.n if dn else 0,
            "window_ms": ms(self.window_s),
            "bin_ms": ms(self.bin_s),
            "model": {"cell": None if self.cell is None else self.cell.as_dict(),
                      "thrust_square_law": self.square_law},
        }
        for name, d in (("up", up), ("down", dn)):
            out[f"summary_{name}"] = None if d is None else {
                "from": d.describe(), "edges": list(d.fitted_edges)}
        out["notes"] = list(self.notes)
        for name, d in (("up", up), ("down", dn)):
            if d is not None and d.second_order is not None:
                so = d.second_order
                out[f"second_order_{name}"] = {"latency_ms": ms(so.latency_s),
                                               "tau1_ms": ms(so.tau1_s), "tau2_ms": ms(so.tau2_s),
                                               "gain": num(so.gain), "rms": num(so.rms)}
        used = {i for g in self.groups for i in g.edges}
        fits = {i: f for g in self.groups for i, f in zip(g.edges, g.singles, strict=True)}
        why_not = dict(self.excluded)
        out["edges"] = [
            {"t_s": round(e.t_s, 6), "direction": e.direction, "u_before": e.u_before,
             "u_after": e.u_after, "step": e.step, "used": i in used,
             "fitted": i in fits and fits[i].fitted,
             **({"latency_ms": ms(fits[i].latency_s), "tau_ms": ms(fits[i].tau_s),
                 "gain": num(fits[i].gain), "t63_ms": ms(fits[i].t63_s)}
                if i in fits and fits[i].fitted else {}),
             **({"why": fits[i].why} if i in fits and not fits[i].fitted else {}),
             **({} if i in used else
                {"why": why_not.get(i, "level held too briefly before or after")})}
            for i, e in enumerate(self.edges)
        ]
        return out


def _bin_window(t: np.ndarray, y: np.ndarray, t_edge: float, pre_s: float, post_s: float,
                bin_s: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Mean time, mean value and count per bin of [t_edge - pre, t_edge + post)."""
    nb = round((pre_s + post_s) / bin_s)
    i0 = np.searchsorted(t, t_edge - pre_s, side="left")
    i1 = np.searchsorted(t, t_edge - pre_s + nb * bin_s, side="left")
    tt, yy = t[i0:i1] - t_edge, y[i0:i1]
    good = np.isfinite(yy)
    tt, yy = tt[good], yy[good]
    k = np.clip(((tt + pre_s) / bin_s).astype(np.int64), 0, nb - 1)
    cnt = np.bincount(k, minlength=nb).astype(float)
    with np.errstate(invalid="ignore", divide="ignore"):
        tb = np.bincount(k, tt, minlength=nb) / cnt
        yb = np.bincount(k, yy, minlength=nb) / cnt
    centre = (np.arange(nb) + 0.5) * bin_s - pre_s
    tb = np.where(cnt > 0, tb, centre)
    return tb, yb, cnt


def _direct_levels(tb: np.ndarray, yb: np.ndarray) -> tuple[float, float]:
    pre = (tb < 0) & np.isfinite(yb)
    post = np.isfinite(yb) & (tb >= 0)
    y0 = float(np.mean(yb[pre])) if pre.any() else math.nan
    tail = post & (tb >= 0.8 * np.max(tb[post])) if post.any() else post
    y1 = float(np.mean(yb[tail])) if tail.any() else math.nan
    return y0, y1


def _crossing(tb: np.ndarray, z: np.ndarray, level: float) -> float:
    """Time of the last upward crossing of ``level`` before z first reaches 0.9 (noise
    before the rise cannot trigger it), interpolated between bins."""
    ok = np.isfinite(z) & (tb >= 0)
    tb, z = tb[ok], z[ok]
    high = np.flatnonzero(z >= max(0.9, level))
    stop = int(high[0]) if high.size else z.size - 1
    below = np.flatnonzero(z[: stop + 1] < level)
    if below.size == 0:
        return float(tb[0]) if z.size else math.nan
    j = int(below[-1])
    if j + 1 >= z.size:
        return math.nan
    frac = (level - z[j]) / (z[j + 1] - z[j])
    return float(tb[j] + frac * (tb[j + 1] - tb[j]))


def _fit_first_order(tb: np.ndarray, yb: np.ndarray, cnt: np.ndarray, step: float,
                     post_s: float, cell: CellDynamics | None = None,
                     square: bool = False, start: FirstOrderFit | None = None
                     ) -> FirstOrderFit:
    """Least squares of ``thrust_step`` to one window; ``start``: a fit of the same
    response (the mean of the repeats) whose latency and tau one edge's fit starts from,
    nearer than its own noisy crossings (fewer iterations, the same minimum). An edge's
    fit (``start`` given) leaves ``model_t63_s`` NaN: only the mean's is reported."""
    y0d, y1d = _direct_levels(tb, yb)
    use = np.isfinite(yb) & (cnt > 0)
    why = ""
    if use.sum() < MIN_BINS:
        why = (f"{int(use.sum())} of {tb.size} bins hold samples (need {MIN_BINS}): the "
               "signal is sampled too slowly for this window")
    elif not (math.isfinite(y0d) and math.isfinite(y1d)):
        why = "no samples before the edge or at the end of the window"
    elif y1d == y0d:
        why = "the signal does not change (e.g. the rotor does not turn at either level)"
    if why:
        return FirstOrderFit(*(math.nan,) * 7, ok=False, why=why)
    z = (yb - y0d) / (y1d - y0d)
    t63 = _crossing(tb, z, T63)
    t28 = _crossing(tb, z, T28)
    tau0 = 1.5 * (t63 - t28) if math.isfinite(t63 - t28) and t63 > t28 else 0.1 * post_s
    lat0 = min(max(t63 - tau0, 0.0), 0.4 * post_s) if math.isfinite(t63) else 0.0
    tau0 = min(max(tau0, 1e-4), 1.9 * post_s)
    tt, yy, w = tb[use], yb[use], np.sqrt(cnt[use])
    scale = abs(y1d - y0d)

    def resid(p: np.ndarray) -> np.ndarray:
        return w * (thrust_step(tt, p[0], p[1], p[2], p[3], cell, square) - yy) / scale

    def jac(p: np.ndarray) -> np.ndarray:  # analytic: finite differences cost 4 models
        return thrust_step_jacobian(tt, p[0], p[1], p[2], p[3], cell, square)[1] * (
            w / scale)[:, None]

    if cell is not None:  # the cell's group delay is the cell's, not the plant's latency
        lat0 = max(lat0 - cell.group_delay_s, 0.0)
    if start is not None and start.fitted:
        lat0 = min(max(start.latency_s, 0.0), 0.4 * post_s)
        tau0 = min(max(start.tau_s, 1e-4), 1.9 * post_s)
    lo = [0.0, 1e-4, -np.inf, -np.inf]
    hi = [0.5 * post_s, 2.0 * post_s, np.inf, np.inf]
    sol = least_squares(resid, [lat0, tau0, y0d, y1d],
                        jac=jac,  # pyright: ignore[reportArgumentType] (stub: str only)
                        bounds=(lo, hi), x_scale="jac")
    lat, tau, y0, y1 = (float(v) for v in sol.x)
    model = thrust_step(tt, lat, tau, y0, y1, cell, square)
    rms = float(np.sqrt(np.average((model - yy) ** 2, weights=cnt[use])))
    u_lat, u_tau = _fit_uncertainty(sol.jac, sol.fun, 4)
    ok, why = bool(sol.success), "" if sol.success else f"the solver failed ({sol.message})"
    if ok and tau >= 0.99 * hi[1]:
        ok, why = False, f"tau runs into its bound ({tau * 1e3:.0f} ms): no settling in the window"
    if ok and y1 != y0:
        # read against the fitted levels: the mean of the window's end is below the final
        # value when the level is held less than ~3 tau, and the 63 % of that lower change
        # came before latency + tau (Table C.1's t63 = L + tau; read against the window's end
        # it gave t63 161 ms against L + tau 180 ms with a 0.5 s hold and tau 166 ms)
        t63 = _crossing(tb, (yb - y0) / (y1 - y0), T63)
    model_t63 = math.nan
    if start is None:  # the model's 63 % crossing on a fine grid: the mean's, for summary()
        grid = np.linspace(0.0, lat + 8.0 * tau, 4001)
        z_model = (thrust_step(grid, lat, tau, y0, y1, cell, square) - y0) / (y1 - y0)
        model_t63 = _crossing(grid, z_model, T63)
    return FirstOrderFit(lat, tau, (y1 - y0) / step, y0, y1, rms, t63, ok, why, u_lat, u_tau,
                         model_t63)


def _fit_uncertainty(jac: np.ndarray, resid: np.ndarray, params: int) -> tuple[float, float]:
    """Standard uncertainties of the first two parameters: V = s^2 (J'J)^-1 with s^2 the
    residual variance (the bins' weights are relative, not absolute: GUM-style Type A of a
    least-squares fit, nu = N - p); NaN when the fit has no degrees of freedom left."""
    dof = resid.size - params
    if dof <= 0:
        return math.nan, math.nan
    try:
        cov = np.linalg.pinv(jac.T @ jac) * float(resid @ resid) / dof
    except np.linalg.LinAlgError:
        return math.nan, math.nan
    d = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    return float(d[0]), float(d[1])


def _fit_second_order(tb: np.ndarray, yb: np.ndarray, cnt: np.ndarray, step: float,
                      post_s: float, first: FirstOrderFit) -> SecondOrderFit:
    use = np.isfinite(yb) & (cnt > 0)
    tt, yy, w = tb[use], yb[use], np.sqrt(cnt[use])
    scale = abs(first.y1 - first.y0) or 1.0

    def resid(p: np.ndarray) -> np.ndarray:
        m = p[3] + (p[4] - p[3]) * second_order_step(tt, p[0], p[1], p[1] * p[2])
        return w * (m - yy) / scale

    best = None
    for r0 in (0.1, 0.5):  # two starts: a fast second pole, or two similar ones
        x0 = [max(first.latency_s - 0.5 * r0 * first.tau_s, 0.0), first.tau_s * (1 - 0.5 * r0),
              r0, first.y0, first.y1]
        x0[1] = min(max(x0[1], 1e-4), 1.9 * post_s)
        sol = least_squares(resid, x0, bounds=([0.0, 1e-4, 1e-3, -np.inf, -np.inf],
                                               [0.5 * post_s, 2.0 * post_s, 0.999, np.inf,
                                                np.inf]), x_scale="jac")
        if best is None or sol.cost < best.cost:
            best = sol
    assert best is not None
    lat, tau1, r, y0, y1 = (float(v) for v in best.x)
    m = y0 + (y1 - y0) * second_order_step(tt, lat, tau1, tau1 * r)
    rms = float(np.sqrt(np.average((m - yy) ** 2, weights=cnt[use])))
    return SecondOrderFit(lat, tau1, tau1 * r, (y1 - y0) / step, y0, y1, rms)


def _mean_window(rows: list[tuple[np.ndarray, np.ndarray, np.ndarray]]
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The bins of several edge windows averaged: mean time, mean value, summed count."""
    y_all = np.stack([r[1] for r in rows])
    # bins no edge filled (a slow or multi-rate signal) stay NaN: numpy's "Mean of empty
    # slice" warning about them is expected, not news for the user
    with np.errstate(invalid="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        tb = np.nanmean(np.stack([r[0] for r in rows]), axis=0)
        y_mean = np.nanmean(y_all, axis=0) if len(rows) > 1 else y_all[0]
    return tb, y_mean, np.stack([r[2] for r in rows]).sum(axis=0)


def _inconsistent_repeats(singles: tuple[FirstOrderFit, ...]) -> list[str]:
    """For each edge of a group, why its single fit is no repeat of the others' response
    ("" where it is one; module doc). Needs three fitted edges; flags only a minority."""
    none = [""] * len(singles)
    fitted = [f for f in singles if f.fitted]
    median = float(np.median([f.tau_s for f in fitted])) if len(fitted) >= 3 else math.nan
    if not median > 0:
        return none

    def odd(f: FirstOrderFit) -> bool:
        ratio = f.tau_s / median
        sure = not math.isfinite(f.u_tau_s) or abs(f.tau_s - median) > \
            REPEAT_TAU_SIGMAS * f.u_tau_s
        return f.fitted and sure and not 1 / REPEAT_TAU_RATIO <= ratio <= REPEAT_TAU_RATIO

    why = [f"no repeat of its group's response: tau {f.tau_s * 1e3:.1f} ms (latency "
           f"{f.latency_s * 1e3:.1f} ms) against the repeats' median {median * 1e3:.1f} ms "
           "(a stall bunched its samples, or a dropout)" if odd(f) else "" for f in singles]
    # a majority left out would leave none to stand for the actuator's response
    return why if 2 * sum(map(bool, why)) < len(fitted) else none


def _latency_shifts(singles: tuple[FirstOrderFit, ...], mean: FirstOrderFit, pre_s: float
                    ) -> np.ndarray | None:
    """Each edge's latency less the edges' mean (s), when they scatter by more than their
    fits' noise explains and more than ``ALIGN_TAUS`` of tau (module doc); else None. An
    edge without a fit is not moved; a scatter wider than the window's lead-in is no
    jitter of one actuator and is left alone."""
    good = [f for f in singles if f.fitted]
    if len(good) < 3 or not mean.fitted:
        return None
    lat = np.array([f.latency_s for f in good])
    noise = np.array([f.u_latency_s for f in good])
    beyond = float(np.var(lat, ddof=1)) - float(np.nanmean(noise ** 2)) \
        if np.isfinite(noise).any() else float(np.var(lat, ddof=1))
    if beyond <= (ALIGN_TAUS * mean.tau_s) ** 2:
        return None
    centre = float(np.mean(lat))
    shifts = np.array([f.latency_s - centre if f.fitted else 0.0 for f in singles])
    return shifts if float(np.max(np.abs(shifts))) < pre_s else None


def fit_step_response(
    t: np.ndarray,
    y: np.ndarray,
    u: np.ndarray,
    setpoint: np.ndarray | None = None,
    event_t: np.ndarray | None = None,
    *,
    window_s: float = 0.5,
    pre_s: float = 0.05,
    bin_s: float | None = None,
    min_hold_s: float = 0.15,
    second_order: bool = False,
    signal: str = "y",
    command: str = "u",
    gain_unit: str = "",
    speed: np.ndarray | None = None,
    cell: CellDynamics | None = None,
    square_law: bool = False,
) -> StepResponse:
    """Find the edges of ``u`` and fit the response ``y`` around each; see module doc.

    Edges whose level was held less than ``min_hold_s`` before or after are listed but
    not fitted (e.g. the short excursions of Step 2), and so are rising edges that start
    the rotor from rest when its ``speed`` (rpm, same rows as ``t``) is known. The fit
    window is ``window_s`` after the edge, shortened to the shortest hold of the fitted
    edges.
    """
    t = np.asarray(t, float)
    y = np.asarray(y, float)
    edges = detect_edges(t, u, setpoint, event_t)
    if not edges:
        raise LogError(f"{command}: no step edges found in the command column")
    usable = [i for i, e in enumerate(edges)
              if e.hold_before_s >= max(min_hold_s, pre_s) and e.hold_after_s >= min_hold_s]
    if not usable:
        raise LogError(f"{command}: {len(edges)} edges found but none held >= {min_hold_s:g} s "
                       "before and after (nothing settles; use Step 1 for the fit)")
    starts = _starts_from_rest(t, speed, [edges[i] for i in usable])
    excluded = tuple((i, START_WHY) for i, start in zip(usable, starts, strict=True) if start)
    usable = [i for i, start in zip(usable, starts, strict=True) if not start]
    if not usable:
        raise LogError(f"{command}: every edge held long enough is a {START_WHY}: nothing to "
                       "fit (step between running levels)")
    post_s = min(window_s, min(edges[i].hold_after_s for i in usable))
    dt = float(np.median(np.diff(t))) if t.size > 1 else 0.0
    if bin_s is None:
        bin_s = 0.0005
    bin_s = max(bin_s, dt)
    if post_s < 10 * bin_s:
        raise LogError(f"{signal}: the sample rate ({1 / dt:.3g} Hz) is too low for a step fit "
                       f"over {post_s:g} s")

    # group edges of the same direction and levels (Step 1 has one group per direction)
    keys: dict[tuple[str, float, float], list[int]] = {}
    span = max(abs(e.u_after - e.u_before) for e in edges)
    for i in usable:
        e = edges[i]
        q = 0.02 * span
        keys.setdefault((e.direction, round(e.u_before / q), round(e.u_after / q)), []).append(i)

    def mean_fit(rows: list[tuple[np.ndarray, np.ndarray, np.ndarray]], steps: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray, float, FirstOrderFit]:
        """The repeats' mean window (bin times, values, counts), mean step and its fit."""
        tb, y_mean, cnt = _mean_window(rows)
        step = float(np.mean(steps))
        return tb, y_mean, cnt, step, _fit_first_order(tb, y_mean, cnt, step, post_s, cell,
                                                       square_law)

    groups: list[DirectionFit] = []
    for (direction, _, _), idx in keys.items():
        rows = [_bin_window(t, y, edges[i].t_s, pre_s, post_s, bin_s) for i in idx]
        steps = np.array([edges[i].step for i in idx])
        tb, y_mean, cnt, step, mean = mean_fit(rows, steps)
        singles = tuple(_fit_first_order(r[0], r[1], r[2], float(s), post_s, cell, square_law,
                                         start=mean)
                        for r, s in zip(rows, steps, strict=True))
        odd = _inconsistent_repeats(singles)
        if any(odd):
            excluded += tuple((i, w) for i, w in zip(idx, odd, strict=True) if w)
            keep = [k for k, w in enumerate(odd) if not w]
            idx, rows, steps = [idx[k] for k in keep], [rows[k] for k in keep], steps[keep]
            singles = tuple(singles[k] for k in keep)
            tb, y_mean, cnt, step, mean = mean_fit(rows, steps)
        window_s_used = post_s
        shifts = _latency_shifts(singles, mean, pre_s)
        if shifts is not None:
            post_a = post_s - float(np.max(shifts))  # no window reads past its hold
            tb_a, y_a, cnt_a = _mean_window(
                [_bin_window(t, y, edges[i].t_s + d, pre_s, post_a, bin_s)
                 for i, d in zip(idx, shifts, strict=True)])
            aligned = _fit_first_order(tb_a, y_a, cnt_a, step, post_a, cell, square_law)
            # the aligned windows start at each edge plus its shift: the mean fit's latency
            # is the edges' mean latency, as the plain mean's would be without the scatter
            if aligned.fitted:
                mean, tb, y_mean, cnt, window_s_used = aligned, tb_a, y_a, cnt_a, post_a
            else:
                shifts = None
        so = _fit_second_order(tb, y_mean, cnt, step, window_s_used, mean) \
            if second_order and mean.ok else None
        good = [s for s in singles if s.fitted]
        groups.append(DirectionFit(
            direction=direction,
            u_before=float(np.mean([edges[i].u_before for i in idx])),
            u_after=float(np.mean([edges[i].u_after for i in idx])),
            step=step,
            edges=tuple(idx),
            mean=mean,
            singles=singles,
            latency=Estimate.of(mean.latency_s, np.array([s.latency_s for s in good])),
            tau=Estimate.of(mean.tau_s, np.array([s.tau_s for s in good])),
            gain=Estimate.of(mean.gain, np.array([s.gain for s in good])),
            t63=Estimate.of(mean.t63_s, np.array([s.t63_s for s in good])),
            t_s=tb,
            y_mean=y_mean,
            second_order=so,
            aligned=shifts is not None,
        ))

    up, down = _headline(groups, "up"), _headline(groups, "down")
    hold = min(edges[i].hold_after_s for i in usable)
    return StepResponse(signal, command, gain_unit, tuple(edges), tuple(groups), up, down,
                        rise_fall_rms(up, down), post_s, bin_s,
                        notes=short_hold_notes(hold, up, down), excluded=excluded,
                        cell=cell, square_law=square_law)


#: A level held this many time constants has settled to within 2 % (e^-4) before it
#: changes: the usual settling time of a first-order lag. At 3 tau (95 %) the mean of the
#: window's end, which the fit starts from, is still 7 % short of the final level.
SETTLE_TAUS = 4.0


def short_hold_notes(hold_s: float, up: DirectionFit | None, down: DirectionFit | None
                     ) -> tuple[str, ...]:
    """A note when the levels are held less than ``SETTLE_TAUS`` time constants: the
    response has not settled when the command changes, so the final level and tau are the
    fit's extrapolation (and the rising and falling responses overlap)."""
    taus = {d.direction: d.tau.value for d in (up, down)
            if d is not None and math.isfinite(d.tau.value)}
    if not taus or hold_s >= SETTLE_TAUS * max(taus.values()):
        return ()
    which = ", ".join(f"tau_{k} {v * 1e3:.0f} ms" for k, v in taus.items())
    need = SETTLE_TAUS * max(taus.values())
    return (f"levels held {hold_s:.3g} s, less than {SETTLE_TAUS:g} tau ({which}): the "
            "response has not settled when the level changes, so the final level and tau "
            f"are extrapolated by the fit; hold each level at least {math.ceil(need * 10) / 10:g}"
            " s (step --hold) to measure them",)


def _starts_from_rest(t: np.ndarray, speed: np.ndarray | None, edges: list[Edge]
                      ) -> list[bool]:
    """Per edge: a rising edge whose speed samples of the ``REST_WINDOW_S`` before it (the
    last sample if none lies there) are all at most ``REST_FRACTION`` of the top speed."""
    if speed is None:
        return [False] * len(edges)
    v = np.abs(np.asarray(speed, float))
    ok = np.isfinite(v)
    top = float(np.max(v[ok])) if ok.any() else 0.0
    if not top > 0:
        return [False] * len(edges)
    out = []
    for e in edges:
        before = ok & (t < e.t_s)
        win = before & (t >= e.t_s - REST_WINDOW_S)
        vals = v[win] if win.any() else v[before][-1:]
        out.append(e.direction == "up" and vals.size > 0
                   and bool(np.all(vals <= REST_FRACTION * top)))
    return out


def _headline(groups: list[DirectionFit], direction: str) -> DirectionFit | None:
    """The numbers a direction reports, built only from edges that gave an estimate: the
    mean-of-repeats fit of the most repeated level pair (Step 1, Table C.1) when a pair
    has >= 2 fitted repeats, else the mean of the single-edge fits of every level pair
    (hand-set steps through the range); None if no edge of that direction was fitted."""
    mine = [g for g in groups if g.direction == direction]
    repeated = [g for g in mine if g.mean.fitted and len(g.fitted_edges) >= 2]
    if repeated:
        return max(repeated, key=lambda g: (len(g.fitted_edges), abs(g.step)))
    fitted = [g for g in mine if g.fitted_edges]
    if not fitted:
        return None
    if len(fitted) == 1 and fitted[0].mean.fitted:
        return fitted[0]
    pairs = [(i, f) for g in fitted for i, f in zip(g.edges, g.singles, strict=True)
             if f.fitted]
    fits = [f for _, f in pairs]
    steps = [(f.y1 - f.y0) / f.gain if f.gain else math.nan for f in fits]

    def avg(name: str) -> float:
        return float(np.mean([getattr(f, name) for f in fits]))

    show = max(fitted, key=lambda g: abs(g.step))  # the curve a figure shows
    mean = FirstOrderFit(avg("latency_s"), avg("tau_s"), avg("gain"), show.mean.y0,
                         show.mean.y1, avg("rms"), finite_mean([f.t63_s for f in fits]))
    return DirectionFit(
        direction=direction,
        u_before=float(np.mean([g.u_before for g in fitted])),
        u_after=float(np.mean([g.u_after for g in fitted])),
        step=finite_mean(steps),
        edges=tuple(i for i, _ in pairs),
        mean=mean,
        singles=tuple(fits),
        latency=Estimate.of(mean.latency_s, np.array([f.latency_s for f in fits])),
        tau=Estimate.of(mean.tau_s, np.array([f.tau_s for f in fits])),
        gain=Estimate.of(mean.gain, np.array([f.gain for f in fits])),
        t63=Estimate.of(mean.t63_s, np.array([f.t63_s for f in fits])),
        t_s=show.t_s,
        y_mean=show.y_mean,
        pooled=True,
    )


def rise_fall_rms(up: DirectionFit | None, down: DirectionFit | None,
                  window_s: float = 0.5) -> float:
    """Table C.1 RMS: sqrt(mean((R_i - F_i)^2)) of the absolute changes of the mean rising
    and falling responses over ``window_s`` from the edge."""
    if up is None or down is None or up.pooled or down.pooled:
        return math.nan  # different level pairs: their changes are not comparable
    n = min(up.t_s.size, down.t_s.size)
    tb = up.t_s[:n]
    sel = (tb >= 0) & (tb <= window_s)
    r = np.abs(up.y_mean[:n] - up.mean.y0)
    f = np.abs(down.y_mean[:n] - down.mean.y0)
    d = (r - f)[sel]
    d = d[np.isfinite(d)]
    return float(np.sqrt(np.mean(d**2))) if d.size else math.nan


# --- runs -----------------------------------------------------------------------------------

SIGNALS = {"thrust": "thrust_n", "rpm": "rpm"}
# command columns tried in order when none is named: a thrust setpoint is also the gain's
# denominator, so it is taken as the command only when there is no ESC command
COMMANDS = ("throttle_us", "thrust_setpoint_n", "duty_pct")
_COMMAND_UNITS = {"throttle_us": "us", "thrust_setpoint_n": "N", "duty_pct": "%"}
STATIC_HINT = ("for a log without command steps use the static analysis (`rotorbench report "
               "RUN`, `rotorbench export ardupilot|px4|gazebo RUN`)")


def _has_data(record: RunRecord, col: str) -> bool:
    return col in record.samples.columns and bool(np.isfinite(record.column(col)).any())


def _command(record: RunRecord, command: str | None) -> str:
    """The command column: the one named, else the first of ``COMMANDS`` with data."""
    if command is not None:
        if command not in record.samples.columns:
            raise LogError(f"{record.path}: --command {command}: no such column (columns: "
                           f"{', '.join(map(str, record.samples.columns))})")
        if not _has_data(record, command):
            raise LogError(f"{record.path}: --command {command}: the column is empty; "
                           f"{STATIC_HINT}")
        return command
    for name in COMMANDS:
        if _has_data(record, name):
            return name
    raise LogError(f"{record.path}: no command column with data ({', '.join(COMMANDS)}; name "
                   f"another with --command COL): nothing to fit a step to; {STATIC_HINT}")


def signal_period(t: np.ndarray, y: np.ndarray) -> float:
    """Median time between the samples that hold a value (a load cell logged on every
    sixth row of a stand log has six times the row period)."""
    tt = t[np.isfinite(y)]
    d = np.diff(tt)
    d = d[d > 0]
    return float(np.median(d)) if d.size else math.inf


def _too_slow(col: str, period: float, tau: float, source: str) -> str:
    return (f"{col}: sampled every {period * 1e3:.3g} ms ({1 / period:.3g} Hz), "
            f"{tau / period:.2g} samples per time constant (tau {tau * 1e3:.3g} ms from "
            f"{source}; need >= {MIN_SAMPLES_PER_TAU:g})")


def _fitted_tau(res: StepResponse) -> float:
    taus = [d.tau.value for d in (res.up, res.down) if d is not None]
    taus = [x for x in taus if math.isfinite(x)]
    return float(np.mean(taus)) if taus else math.nan


def fit_run(record: RunRecord, signal: str = "auto", command: str | None = None,
            **kwargs: Any) -> StepResponse:
    """Fit the step responses of a run folder.

    ``command`` names the command column (default: throttle_us, thrust_setpoint_n, then an
    ESC's duty_pct). ``signal`` is thrust, rpm or auto: thrust if logged and fast enough,
    else rpm. A signal is refused with its reason when it has fewer than
    ``MIN_SAMPLES_PER_TAU`` samples per time constant (e.g. a stand's load cell at 6.6 Hz
    under a 50 ms rotor) or no edge gives an estimate; auto then fits the next signal and
    says which was used (``StepResponse.notes``). The gain is per setpoint newton when the
    run has thrust setpoints, else per unit of the command. Errors name the run."""
    if signal != "auto" and signal not in SIGNALS:
        raise LogError(f"signal {signal!r}: expected one of auto, {', '.join(SIGNALS)}")
    cmd = _command(record, command)
    t = record.column("t_s")
    u = record.column(cmd)
    sp = record.column("thrust_setpoint_n") if _has_data(record, "thrust_setpoint_n") else None
    speed = record.column("rpm") if _has_data(record, "rpm") else None
    names = list(SIGNALS) if signal == "auto" else [signal]
    cands = [n for n in names if _has_data(record, SIGNALS[n])]
    if not cands:
        cols = " or ".join(repr(SIGNALS[n]) for n in names)
        raise LogError(f"{record.path}: column {cols} has no data to fit")
    kwargs.setdefault("bin_s", None)
    unit = "N" if sp is not None else _COMMAND_UNITS.get(cmd, f"unit of {cmd}")
    why: dict[str, str] = {}
    periods: dict[str, float] = {}
    for name in cands:  # in order; the first signal that resolves its time constant wins
        col = SIGNALS[name]
        y = record.column(col)
        periods[name] = period = signal_period(t, y)
        # a bench run's thrust is tared (zero-referenced): the square law of (E.1) holds;
        # its cell's mechanics are modelled where the run declares them
        thrust = col == "thrust_n"
        model = {"cell": CellDynamics.from_meta(record.meta, col) if thrust else None,
                 "square_law": thrust and record.thrust_zeroed()}
        try:
            res = fit_step_response(t, y, u, sp, event_times(record), signal=col, command=cmd,
                                    gain_unit=f"{'N' if thrust else 'rpm'}/{unit}",
                                    speed=speed, **{**model, **kwargs})
        except LogError as exc:
            msg = str(exc)
            if "no step edges" in msg or "none held" in msg:
                raise LogError(f"{record.path}: {msg}; {STATIC_HINT}") from None
            why[name] = msg
            continue
        tau = _fitted_tau(res)
        if res.up is None and res.down is None:
            first = next((f.why for g in res.groups for f in g.singles if f.why), "")
            why[name] = (f"{col}: sampled every {period * 1e3:.3g} ms; no edge gave an "
                         f"estimate ({first or 'no usable edge'})")
        elif tau / period < MIN_SAMPLES_PER_TAU:
            why[name] = _too_slow(col, period, tau, col)
        else:
            # an earlier signal that failed: say whether it is too slow for this tau
            notes = []
            for n, reason in why.items():
                if tau / periods[n] < MIN_SAMPLES_PER_TAU:
                    reason = _too_slow(SIGNALS[n], periods[n], tau, col)
                notes.append(f"not fitted: {reason}")
            if notes:
                notes.append(f"fitted {col} instead")
            return replace(res, notes=(*notes, *res.notes))
    raise LogError(f"{record.path}: no signal can be fitted: " + "; ".join(
        why[n] for n in cands))


def frame_period(record: RunRecord) -> float:
    """ESC frame period of the run (for judging the latency resolution), NaN if unknown."""
    return esc_frame_s(record)


def as_dict(fit: FirstOrderFit) -> dict[str, float]:
    return {k: float(v) for k, v in asdict(fit).items()}
