"""A sensor calibration as one figure: the held readings against the weights' force, up
and down, with the fitted line; under it each point's deviation from the line in per cent
of full scale, where non-linearity and hysteresis show."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from analysis.figures import _save

__all__ = ["plot_calibration"]


def plot_calibration(record: dict[str, Any], path: Path) -> Path:
    """PNG of a calibration record (``rotorbench calibrate-sensors``) at ``path``."""
    import matplotlib.pyplot as plt

    res = record["result"]
    pts = res["points"]
    unit = "N m" if record["applies"]["channel"] == "torque_nm" else "N"
    f = np.array([p["force"] for p in pts])
    y = np.array([p["reading"] for p in pts])
    up = np.array([p["direction"] == "up" for p in pts])
    gain, offset = res["scale"], res["offset"]
    line = offset + f / gain
    fso = abs(f.max() / gain)
    dev = (y - line) / fso * 100.0
    fig, (top, bottom) = plt.subplots(2, 1, figsize=(7.0, 6.0), sharex=True,
                                      gridspec_kw={"height_ratios": (3, 2)})
    grid = np.linspace(0.0, f.max(), 50)
    top.plot(grid, offset + grid / gain, color="0.5", lw=1, label="fitted line")
    top.plot(f[up], y[up], "^", color="C0", label="loading")
    top.plot(f[~up], y[~up], "v", color="C3", label="unloading")
    top.set_ylabel(f"reading ({unit}, before calibration)")
    top.legend(loc="upper left")
    ch = res["characteristics_fraction_of_full_scale"]
    top.set_title(f"{record['sensor']['role']} {record['applies']['channel']}: gain "
                  f"{gain:.5g} +- {2 * res['u_scale']:.2g} (k = 2); non-linearity "
                  f"{ch['nonlinearity'] * 100:.3g} %, hysteresis {ch['hysteresis'] * 100:.3g} %",
                  fontsize=9)
    bottom.axhline(0.0, color="0.5", lw=1)
    bottom.plot(f[up], dev[up], "^-", color="C0")
    bottom.plot(f[~up], dev[~up], "v-", color="C3")
    bottom.set_xlabel(f"reference ({unit}): weights x local g"
                      + (" x arm" if unit == "N m" else ""))
    bottom.set_ylabel("from the line (% of full scale)")
    fig.tight_layout()
    return _save(fig, path)
