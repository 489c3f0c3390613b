"""Figures of a flown design: maneuver responses (like Paper B Figs. B.6-B.8) and the
time-constant ranking scatter.

Drawn for ``rotorbench fly --plot`` and by docs/flight_figures.py; beside
``bench.figures.sizing_figures`` (the figures of ``evaluate`` and ``pareto``) so no command owns
what another script needs.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

AXIS = {"roll": (0, "roll (deg)"), "pitch": (1, "pitch (deg)"), "yaw": (2, "yaw (deg)")}


def pyplot() -> Any:
    """matplotlib.pyplot on the Agg backend (files only, no display needed)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def maneuver_figures(flights: dict[str, Any], vehicle: Any, out: Path) -> list[Path]:
    """One PNG per maneuver: the commanded axis against its setpoint, and rotor speeds."""
    plt = pyplot()
    out.mkdir(parents=True, exist_ok=True)
    paths = []
    rpm = 60.0 / (2.0 * math.pi)
    for name, f in flights.items():
        fig, (ax1, ax2) = plt.subplots(2, 1, figsize=(7, 5.5), sharex=True)
        axis = f.maneuver.axis
        if axis in AXIS:
            col, label = AXIS[axis]
            ax1.plot(f.t, np.degrees(f.euler[:, col]), label="response")
            ax1.plot(f.t, np.degrees(f.setpoint), "--", label="setpoint")
            ax1.set_ylabel(label)
        elif axis in ("altitude", "hover"):
            ax1.plot(f.t, f.position[:, 2], label="height")
            ax1.plot(f.t, f.setpoint, "--", label="setpoint")
            ax1.set_ylabel("height (m)")
        else:
            for col, label in ((0, "roll"), (1, "pitch")):
                ax1.plot(f.t, np.degrees(f.euler[:, col]), label=label)
            ax1.set_ylabel("attitude (deg)")
        ax1.legend(loc="best")
        ax1.grid(True, alpha=0.3)
        ax1.set_title(f"{name}: {vehicle.label} ({vehicle.layout})")
        for i in range(f.omega.shape[1]):
            ax2.plot(f.t, f.omega[:, i] * rpm, lw=0.8, label=f"rotor {i + 1}")
        ax2.axhline(vehicle.omega_max_rad_s * rpm, color="k", ls=":", lw=0.8,
                    label="full throttle")
        ax2.set_ylabel("rotor speed (rpm)")
        ax2.set_xlabel("time (s)")
        ax2.grid(True, alpha=0.3)
        ax2.legend(loc="best", fontsize=7, ncol=3)
        fig.tight_layout()
        path = out / f"fly_{name}.png"
        fig.savefig(path, dpi=110)
        plt.close(fig)
        paths.append(path)
    return paths


def ranking_scatter(ranking: Any, out: Path, catalog_name: str) -> Path:
    """Time constant against closed-loop roll rise time, one point per design."""
    plt = pyplot()
    out.mkdir(parents=True, exist_ok=True)
    fig, ax = plt.subplots(figsize=(6.5, 4.5))
    ok = [r for r in ranking.rows if not r.note and r.rise_time_ms is not None]
    ax.scatter([r.time_constant_ms for r in ok], [r.rise_time_ms for r in ok], s=18,
               label="designs that hover")
    left = [r for r in ranking.rows if r.note and r.rise_time_ms is not None]
    if left:
        ax.scatter([r.time_constant_ms for r in left], [r.rise_time_ms for r in left],
                   marker="x", color="r", label="cannot hover (not ranked)")
    rho = "n/a" if math.isnan(ranking.rho) else f"{ranking.rho:.3f}"
    ax.set_title(f"{catalog_name}, N = {ranking.actuators}: Spearman rho = {rho}")
    ax.set_xlabel("time constant (ms)")
    ax.set_ylabel("roll rise time 10-90 % (ms)")
    ax.grid(True, alpha=0.3)
    ax.legend(loc="best")
    fig.tight_layout()
    path = out / f"fly_ranking_{catalog_name}_n{ranking.actuators}.png"
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
