"""The flight report's figures: step responses per axis (both estimates), and the gyro
noise against throttle with the rotor and blade-pass lines."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from analysis.figures import _save
from analysis.flight_report import FlightReport

__all__ = ["plot_noise", "plot_step_responses"]


def plot_step_responses(rep: FlightReport, path: Path) -> Path | None:
    import matplotlib.pyplot as plt

    axes = [r for r in rep.responses.values() if r.step is not None]
    if not axes:
        return None
    fig, subs = plt.subplots(1, len(axes), figsize=(4.0 * len(axes), 3.4), squeeze=False)
    for ax, r in zip(subs[0], axes, strict=True):
        assert r.step is not None
        ax.axhline(1.0, color="0.7", lw=1)
        ax.plot(r.t_s * 1e3, r.step, color="C0", label="H1 (Flight Review)")
        if r.step_pa is not None:
            ax.plot(r.t_s * 1e3, r.step_pa, color="C1", ls="--", label="PID-Analyzer")
        m = r.metrics
        ax.set_title(f"{r.axis}: delay {m['delay_ms']:.0f} ms, rise {m['rise_ms']:.0f} ms, "
                     f"overshoot {m['overshoot_pct']:.0f} %", fontsize=9)
        ax.set_xlabel("time (ms)")
        ax.set_ylim(-0.2, 2.0)
    subs[0][0].set_ylabel("response to a unit setpoint step")
    subs[0][0].legend(loc="lower right", fontsize=8)
    fig.tight_layout()
    return _save(fig, path)


def plot_noise(rep: FlightReport, path: Path, blades: int = 2) -> Path | None:
    import matplotlib.pyplot as plt

    m = rep.noise
    if m is None:
        return None
    axes = list(m.psd)
    fig, subs = plt.subplots(1, len(axes), figsize=(4.0 * len(axes), 3.6), squeeze=False,
                             sharey=True)
    centres = 0.5 * (m.throttle_edges[:-1] + m.throttle_edges[1:]) * 100
    for ax, axis in zip(subs[0], axes, strict=True):
        with np.errstate(divide="ignore", invalid="ignore"):
            db = 10 * np.log10(m.psd[axis])
        ax.pcolormesh(m.freqs_hz, centres, db, shading="nearest", cmap="viridis")
        ok = np.isfinite(m.rotor_hz)
        if ok.any():
            ax.plot(m.rotor_hz[ok], centres[ok], "w--", lw=1, label="rotor")
            ax.plot(blades * m.rotor_hz[ok], centres[ok], "w:", lw=1, label="blade pass")
            ax.legend(loc="lower right", fontsize=7)
        ax.set_title(f"gyro {axis}", fontsize=9)
        ax.set_xlabel("frequency (Hz)")
    subs[0][0].set_ylabel("throttle (%)")
    fig.tight_layout()
    return _save(fig, path)
