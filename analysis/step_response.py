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
* the 63 % rise time is read from the data (first crossing of 63.2 % of the change,
  measured from the command edge, so it includes the latency);
* the spread of the single-edge estimates gives each estimate's uncertainty;
* a second-order fit with two real poles (the form of C.1) is available as an option.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np
from scipy.optimize import least_squares

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
    "second_order_step",
]

T63 = 1.0 - math.exp(-1.0)  # 0.632: the response of a first-order lag after one tau
T28 = 1.0 - math.exp(-1.0 / 3.0)  # 0.283: after tau / 3 (two-point method)


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
        if math.isfinite(self.setpoint_before) and math.isfinite(self.setpoint_after):
            return self.setpoint_after - self.setpoint_before
        return self.u_after - self.u_before


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
            "latency_std_ms": ms(float(np.nanmean([e.std for e in lat]))) if lat else None,
            "gain": num(float(np.mean([d.gain.value for d in (up, dn) if d is not None])))
            if (up or dn) else None,
            "gain_up": num(up.gain.value) if up else None,
            "gain_down": num(dn.gain.value) if dn else None,
            "gain_unit": self.gain_unit,
            "rise_fall_rms": num(self.rise_fall_rms),
            "rise_time_63_up_ms": ms(up.t63.value) if up else None,
            "rise_time_63_down_ms": ms(dn.t63.value) if dn else None,
            "repeats_up": up.tau.n if up else 0,
            "repeats_down": dn.tau.n if dn else 0,
            "window_ms": ms(self.window_s),
            "bin_ms": ms(self.bin_s),
        }
        for name, d in (("up", up), ("down", dn)):
            if d is not None and d.second_order is not None:
                so = d.second_order
                out[f"second_order_{name}"] = {"latency_ms": ms(so.latency_s),
                                               "tau1_ms": ms(so.tau1_s), "tau2_ms": ms(so.tau2_s),
                                               "gain": num(so.gain), "rms": num(so.rms)}
        used = {i for g in self.groups for i in g.edges}
        fits = {i: f for g in self.groups for i, f in zip(g.edges, g.singles, strict=True)}
        out["edges"] = [
            {"t_s": round(e.t_s, 6), "direction": e.direction, "u_before": e.u_before,
             "u_after": e.u_after, "step": e.step, "used": i in used,
             **({"latency_ms": ms(fits[i].latency_s), "tau_ms": ms(fits[i].tau_s),
                 "gain": num(fits[i].gain), "t63_ms": ms(fits[i].t63_s)} if i in fits else {})}
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
                     post_s: float) -> FirstOrderFit:
    y0d, y1d = _direct_levels(tb, yb)
    use = np.isfinite(yb) & (cnt > 0)
    if not (math.isfinite(y0d) and math.isfinite(y1d)) or use.sum() < 6 or y1d == y0d:
        return FirstOrderFit(*(math.nan,) * 7, ok=False)
    z = (yb - y0d) / (y1d - y0d)
    t63 = _crossing(tb, z, T63)
    t28 = _crossing(tb, z, T28)
    tau0 = 1.5 * (t63 - t28) if math.isfinite(t63 - t28) and t63 > t28 else 0.1 * post_s
    lat0 = min(max(t63 - tau0, 0.0), 0.4 * post_s) if math.isfinite(t63) else 0.0
    tau0 = min(max(tau0, 1e-4), 1.9 * post_s)
    tt, yy, w = tb[use], yb[use], np.sqrt(cnt[use])
    scale = abs(y1d - y0d)

    def resid(p: np.ndarray) -> np.ndarray:
        return w * (p[2] + (p[3] - p[2]) * first_order_step(tt, p[0], p[1]) - yy) / scale

    lo = [0.0, 1e-4, -np.inf, -np.inf]
    hi = [0.5 * post_s, 2.0 * post_s, np.inf, np.inf]
    sol = least_squares(resid, [lat0, tau0, y0d, y1d], bounds=(lo, hi), x_scale="jac")
    lat, tau, y0, y1 = (float(v) for v in sol.x)
    model = y0 + (y1 - y0) * first_order_step(tt, lat, tau)
    rms = float(np.sqrt(np.average((model - yy) ** 2, weights=cnt[use])))
    return FirstOrderFit(lat, tau, (y1 - y0) / step, y0, y1, rms, t63, bool(sol.success))


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
) -> StepResponse:
    """Find the edges of ``u`` and fit the response ``y`` around each; see module doc.

    Edges whose level was held less than ``min_hold_s`` before or after are listed but
    not fitted (e.g. the short excursions of Step 2). The fit window is ``window_s`` after
    the edge, shortened to the shortest hold of the fitted edges.
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

    groups: list[DirectionFit] = []
    for (direction, _, _), idx in keys.items():
        rows = [_bin_window(t, y, edges[i].t_s, pre_s, post_s, bin_s) for i in idx]
        cnt_all = np.stack([r[2] for r in rows])
        y_all = np.stack([r[1] for r in rows])
        # bins no edge filled (a slow or multi-rate signal) stay NaN: numpy's "Mean of
        # empty slice" warning about them is expected, not news for the user
        with np.errstate(invalid="ignore"), warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            tb = np.nanmean(np.stack([r[0] for r in rows]), axis=0)
            y_mean = np.nanmean(y_all, axis=0) if len(rows) > 1 else y_all[0]
        cnt = cnt_all.sum(axis=0)
        steps = np.array([edges[i].step for i in idx])
        step = float(np.mean(steps))
        singles = tuple(_fit_first_order(r[0], r[1], r[2], float(s), post_s)
                        for r, s in zip(rows, steps, strict=True))
        mean = _fit_first_order(tb, y_mean, cnt, step, post_s)
        so = _fit_second_order(tb, y_mean, cnt, step, post_s, mean) if second_order and \
            mean.ok else None
        e0 = edges[idx[0]]
        groups.append(DirectionFit(
            direction=direction,
            u_before=float(np.mean([edges[i].u_before for i in idx])),
            u_after=float(np.mean([edges[i].u_after for i in idx])),
            step=step,
            edges=tuple(idx),
            mean=mean,
            singles=singles,
            latency=Estimate.of(mean.latency_s, np.array([s.latency_s for s in singles])),
            tau=Estimate.of(mean.tau_s, np.array([s.tau_s for s in singles])),
            gain=Estimate.of(mean.gain, np.array([s.gain for s in singles])),
            t63=Estimate.of(mean.t63_s, np.array([s.t63_s for s in singles])),
            t_s=tb,
            y_mean=y_mean,
            second_order=so,
        ))
        del e0

    def headline(direction: str) -> DirectionFit | None:
        cands = [g for g in groups if g.direction == direction]
        return max(cands, key=lambda g: (len(g.edges), abs(g.step))) if cands else None

    up, down = headline("up"), headline("down")
    return StepResponse(signal, command, gain_unit, tuple(edges), tuple(groups), up, down,
                        rise_fall_rms(up, down), post_s, bin_s)


def rise_fall_rms(up: DirectionFit | None, down: DirectionFit | None,
                  window_s: float = 0.5) -> float:
    """Table C.1 RMS: sqrt(mean((R_i - F_i)^2)) of the absolute changes of the mean rising
    and falling responses over ``window_s`` from the edge."""
    if up is None or down is None:
        return math.nan
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


def _has_data(record: RunRecord, col: str) -> bool:
    return col in record.samples.columns and bool(np.isfinite(record.column(col)).any())


def fit_run(record: RunRecord, signal: str = "auto", **kwargs: Any) -> StepResponse:
    """Fit the step responses of a run folder; ``signal`` is thrust, rpm or auto (thrust
    if the run has a load cell, else rpm). The gain is per setpoint newton when the run
    has thrust setpoints, else per microsecond of command."""
    if signal == "auto":
        signal = "thrust" if _has_data(record, "thrust_n") else "rpm"
    if signal not in SIGNALS:
        raise LogError(f"signal {signal!r}: expected one of auto, {', '.join(SIGNALS)}")
    col = SIGNALS[signal]
    if not _has_data(record, col):
        raise LogError(f"{record.path}: column {col!r} has no data to fit")
    t = record.column("t_s")
    sp = record.column("thrust_setpoint_n") if _has_data(record, "thrust_setpoint_n") else None
    if _has_data(record, "throttle_us"):
        u, command = record.column("throttle_us"), "throttle_us"
    elif sp is not None:
        u, command = sp, "thrust_setpoint_n"
    else:
        raise LogError(f"{record.path}: no command column (throttle_us or thrust_setpoint_n)")
    y_unit = "N" if col == "thrust_n" else "rpm"
    sp_ok = sp is not None
    gain_unit = f"{y_unit}/N" if sp_ok else f"{y_unit}/us"
    kwargs.setdefault("bin_s", None)
    res = fit_step_response(t, record.column(col), u, sp, event_times(record),
                            signal=col, command=command, gain_unit=gain_unit, **kwargs)
    return res


def frame_period(record: RunRecord) -> float:
    """ESC frame period of the run (for judging the latency resolution), NaN if unknown."""
    return esc_frame_s(record)


def as_dict(fit: FirstOrderFit) -> dict[str, float]:
    return {k: float(v) for k, v in asdict(fit).items()}
