"""PNG figures of the sizing commands (matplotlib, Agg): partial load and Pareto fronts."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np


def _save(fig: Any, path: Path) -> Path:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def partial_load_figure(record: dict[str, Any], path: Path) -> Path:
    """Thrust, battery current and efficiency against throttle (eCalc's partial load)."""
    rows = record["partial_load"]
    t = np.array([r["throttle_pct"] for r in rows])
    fig, axes = plt.subplots(1, 3, figsize=(11, 3.4))
    for ax, key, label in zip(
        axes,
        ("thrust_n", "current_a", "efficiency_g_per_w"),
        ("thrust per actuator (N)", "battery current per actuator (A)", "efficiency (g/W)"),
        strict=True,
    ):
        ax.plot(t, [r[key] for r in rows], "o-")
        ax.set_xlabel("throttle (%)")
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
    hover = record.get("hover_throttle_pct")
    if hover is not None:
        for ax in axes:
            ax.axvline(hover, color="grey", ls="--", lw=1)
        axes[0].text(hover, axes[0].get_ylim()[1] * 0.95, " hover", color="grey", va="top")
    fig.suptitle(f"{record['actuators']} x {record['propeller']} / {record['motor']} / "
                 f"{record['battery']} (current model: {record.get('current_model', 'thesis')})",
                 fontsize=10)
    fig.tight_layout()
    return _save(fig, path)


def pareto_figure(doc: dict[str, Any], path: Path) -> Path:
    """The front (line and points) over every feasible design (grey; ``_cloud_label`` says
    what else the grey points are, e.g. the flown designs of a sweep file)."""
    fig, ax = plt.subplots(figsize=(6.4, 4.4))
    cloud = doc.get("_cloud")
    if cloud is not None and len(cloud[0]):
        ax.scatter(cloud[0], cloud[1], s=4, c="0.75",
                   label=doc.get("_cloud_label", "feasible designs"), rasterized=True)
    xs = [d[doc["x_key"]] for d in doc["front"]]
    ys = [d[doc["y_key"]] for d in doc["front"]]
    # the edge of what the front reaches: at an x between two points, the best y is the
    # next point's when x is maximised (only it and those after reach that x), the
    # previous point's when x is minimised
    ax.step(xs, ys, where="pre" if doc.get("x_sense") == "max" else "post", color="C0", lw=1)
    ax.scatter(xs, ys, c="C0", s=18, zorder=3, label=f"Pareto front ({len(xs)})")
    ax.set_xlabel(doc["x_label"])
    ax.set_ylabel(doc["y_label"])
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    ax.set_title(f"{doc['catalog_name']}, N = {', '.join(map(str, doc['actuators']))}",
                 fontsize=10)
    fig.tight_layout()
    return _save(fig, path)
