"""Verification figures in the style of Paper A, Fig. A.7-A.10 (PNG files).

Each figure shows, on the independent verification motion, the hexapod's truth, the
corrected IMU and the raw IMU, so the effect of K, the bias, the lever arm and the time
offset is visible.
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
from matplotlib.axes import Axes
from matplotlib.figure import Figure

from analysis.atomic_files import write_atomically
from analysis.imu_calibration import Calibration, aligned_phase, apply_calibration

__all__ = ["verification_figures"]

_XYZ = ("x", "y", "z")


def _save(fig: Figure, path: Path) -> Path:
    try:
        return write_atomically(path, lambda tmp: fig.savefig(tmp, dpi=110), suffix=".png")
    finally:
        plt.close(fig)


def _panel(ax: Axes, t: np.ndarray, truth: np.ndarray, cor: np.ndarray, raw: np.ndarray,
           label: str, unit: str) -> None:
    ax.plot(t, raw, color="0.6", lw=0.8, label=f"{label} raw (IMU)")
    ax.plot(t, cor, color="tab:blue", lw=0.8, label=f"{label} corrected")
    ax.plot(t, truth, color="tab:red", lw=1.0, label=f"{label} hexapod")
    ax.set_ylabel(unit)
    ax.grid(alpha=0.3)
    ax.legend(loc="upper right", fontsize=7)


def verification_figures(cal: Calibration, df: pd.DataFrame, out_dir: str | Path
                         ) -> list[Path]:
    """Write fig_a7..fig_a10 PNGs for the log's ``verify`` phase; returns their paths."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    d = aligned_phase(df, "verify", cal.time_offset_s)
    _, w, f = apply_calibration(cal, d["t"], d["gyro"], d["acc"])
    t = d["t"] - d["t"][0]
    series = {
        "gyro": (d["omega"], w, d["gyro"], "ω", "rad/s"),
        "acc": (d["f"], f, d["acc"], "a", "m/s²"),
    }
    paths = []
    for name, kind, title in (("fig_a7_gyro_x.png", "gyro", "Fig. A.7 style: gyro x"),
                              ("fig_a8_acc_x.png", "acc", "Fig. A.8 style: accelerometer x")):
        truth, cor, raw, sym, unit = series[kind]
        fig, ax = plt.subplots(figsize=(8, 3.2))
        _panel(ax, t, truth[:, 0], cor[:, 0], raw[:, 0], f"{sym}x", unit)
        ax.set_xlabel("time in verification motion (s)")
        ax.set_title(title)
        fig.tight_layout()
        paths.append(_save(fig, out / name))
    for name, kind, title in (("fig_a9_acc_xyz.png", "acc", "Fig. A.9 style: accelerations"),
                              ("fig_a10_gyro_xyz.png", "gyro", "Fig. A.10 style: rates")):
        truth, cor, raw, sym, unit = series[kind]
        fig, axes = plt.subplots(3, 1, figsize=(8, 7), sharex=True)
        for i, ax in enumerate(axes):
            _panel(ax, t, truth[:, i], cor[:, i], raw[:, i], f"{sym}{_XYZ[i]}", unit)
        axes[-1].set_xlabel("time in verification motion (s)")
        axes[0].set_title(title)
        fig.tight_layout()
        paths.append(_save(fig, out / name))
    return paths
