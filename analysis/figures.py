"""PNG figures shaped like the thesis' Fig. C.9-C.19 (matplotlib, Agg backend).

* ``plot_steps``: the mean rising and falling responses as absolute change of thrust
  (rising solid, falling dashed, as in Fig. C.9-C.12) with the fitted first-order models.
* ``plot_static``: thrust against speed (Fig. C.13) and current against speed (Fig. C.14),
  measured points and fitted curves.
* ``plot_validation``: measured and simulated Step 2 responses, rising on top and falling
  below (Fig. C.16-C.19), averaged over the repeats.
Every figure is written to a temporary file and renamed into place.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.figure import Figure

from analysis.static_curves import RPM_TO_RAD_S, StaticCurves
from analysis.step_response import StepResponse, first_order_step
from analysis.validation import Validation

__all__ = ["plot_static", "plot_steps", "plot_validation"]

G0 = 9.80665


def _save(fig: Figure, path: Path, dpi: int = 90) -> Path:
    path = Path(path)
    tmp = path.with_name(f".{path.stem}.tmp.png")
    fig.savefig(tmp, dpi=dpi)
    plt.close(fig)
    os.replace(tmp, path)
    return path


save_figure = _save  # the other figure modules (analysis.vibration_figures) write alike


def plot_steps(fits: Sequence[tuple[str, StepResponse]], path: Path, title: str = "") -> Path:
    """Fig. C.9-C.12: |change of thrust| after the command edge, per ESC setting."""
    fig, ax = plt.subplots(figsize=(7, 4.2))
    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    grams = all(f.signal == "thrust_n" for _, f in fits)
    scale = 1e3 / G0 if grams else 1.0
    for (label, f), color in zip(fits, colors, strict=False):
        for d, style in ((f.up, "-"), (f.down, "--")):
            if d is None:
                continue
            keep = d.t_s >= 0
            tt = d.t_s[keep]
            ax.plot(tt * 1e3, np.abs(d.y_mean[keep] - d.mean.y0) * scale, style, color=color,
                    lw=1.4, label=f"{label} {'rising' if style == '-' else 'falling'}")
            model = abs(d.mean.y1 - d.mean.y0) * first_order_step(tt, d.mean.latency_s,
                                                                   d.mean.tau_s)
            ax.plot(tt * 1e3, model * scale, ":", color="k", lw=0.8)
    ax.set_xlabel("time from command [ms]")
    ax.set_ylabel(f"|delta thrust| [{'g' if grams else fits[0][1].signal}]")
    ax.set_title(title or "Step response, mean of repeats (model dotted)")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    return _save(fig, path)


def plot_static(static: StaticCurves, path: Path, title: str = "") -> Path:
    """Fig. C.13 and C.14: thrust and current against speed with the fitted polynomials."""
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(9, 3.6))
    w = static.omega
    ww = np.linspace(float(w.min()), float(w.max()), 200)
    if static.thrust_poly is not None:
        a1.plot(w, static.thrust, "o", ms=3, label="measured")
        a1.plot(ww, static.thrust_at(ww), "-", label="fitted (C.13)")
    a1.set_xlabel("speed [rad/s]")
    a1.set_ylabel("thrust [N]")
    a1.grid(alpha=0.3)
    if static.thrust_poly is not None:
        a1.legend(fontsize=8)
    if static.current_poly is not None:
        a2.plot(w, static.current, "o", ms=3, label="measured")
        a2.plot(ww, static.current_at(ww), "-", label="fitted (C.14)")
    a2.set_xlabel("speed [rad/s]")
    a2.set_ylabel("current [A]")
    a2.grid(alpha=0.3)
    if static.current_poly is not None:
        a2.legend(fontsize=8)
    sec = a1.secondary_xaxis("top", functions=(lambda x: x / RPM_TO_RAD_S,
                                               lambda x: x * RPM_TO_RAD_S))
    sec.set_xlabel("rpm")
    fig.suptitle(title or "Static curves")
    fig.tight_layout()
    return _save(fig, path)


def _mean_segment(t: np.ndarray, y: np.ndarray, starts: np.ndarray, length: float
                  ) -> tuple[np.ndarray, np.ndarray]:
    dt = float(np.median(np.diff(t)))
    n = int(length / dt)
    rows = []
    for s in starts:
        i0 = int(np.searchsorted(t, s))
        if i0 + n <= t.size:
            rows.append(y[i0:i0 + n])
    if not rows:
        return np.empty(0), np.empty(0)
    return np.arange(n) * dt, np.nanmean(np.stack(rows), axis=0)


def plot_validation(v: Validation, path: Path, title: str = "") -> Path:
    """Fig. C.16-C.19: Step 2 measured vs the first-order and nonlinear-load models."""
    fig, axes = plt.subplots(2, 1, figsize=(7, 5.5), sharex=True)
    for ax, starts, name in ((axes[0], v.rising_starts, "rising"),
                             (axes[1], v.falling_starts, "falling")):
        if starts.size >= 1:
            other = v.falling_starts if name == "rising" else v.rising_starts
            later = other[other > starts[0]]
            length = float(later[0] - starts[0]) if later.size else 0.8
            for y, style, label in ((v.measured, "-", "measured"),
                                    (v.first_order, "--", "first order (5.1)"),
                                    (v.nonlinear, ":", "nonlinear load (5.2)")):
                if np.isfinite(y).any():
                    tt, ym = _mean_segment(v.t_s, y, starts, length)
                    ax.plot(tt * 1e3, ym, style, label=label)
        else:  # no repeat markers: the whole run
            ax.plot(v.t_s, v.measured, "-", label="measured")
            ax.plot(v.t_s, v.first_order, "--", label="first order (5.1)")
        ax.set_ylabel(f"thrust [N] ({name})")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    axes[1].set_xlabel("time [ms]")
    fig.suptitle(title or f"Step 2: RMS error first order {v.rms_first_order_pct:.1f} %, "
                          f"nonlinear load {v.rms_nonlinear_pct:.1f} % of the band")
    fig.tight_layout()
    return _save(fig, path)
