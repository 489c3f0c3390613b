"""Benches compared as one figure: each constant a panel, each bench's value with its
expanded uncertainty (k = 2) as an error bar; a bench whose E_n against every other bench
is beyond 1 in red, one flagged against some of them in orange, so a reader sees at once
which bench stands apart and by how much."""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path

from analysis.figures import save_figure
from analysis.metrology.interlab import ConstantComparison, flagged_benches

__all__ = ["plot_comparison"]

APART = "C3"  # flagged against every other bench
SOME = "C1"  # flagged against some
AGREES = "C0"


def plot_comparison(comparisons: Sequence[ConstantComparison], path: Path,
                    title: str = "") -> Path:
    """PNG at ``path``: one panel per constant, benches along x; a bench without an
    uncertainty is drawn as a hollow marker without a bar."""
    import matplotlib.pyplot as plt

    n = max(1, len(comparisons))
    cols = min(3, n)
    rows = math.ceil(n / cols)
    fig, axes = plt.subplots(rows, cols, figsize=(3.6 * cols, 2.9 * rows), squeeze=False)
    for ax, c in zip(axes.flat, comparisons, strict=False):
        counts = flagged_benches(c)
        others = len(c.participants) - 1
        for i, p in enumerate(c.participants):
            n = counts[p.bench]
            color = APART if n and n == others else SOME if n else AGREES
            if p.expanded is None:
                ax.plot([i], [p.value], "o", mfc="none", color=color)
            else:
                ax.errorbar([i], [p.value], yerr=[p.expanded], fmt="o", color=color,
                            capsize=4)
        ax.set_xticks(range(len(c.participants)),
                      [p.bench for p in c.participants], rotation=20, fontsize=8)
        ax.set_xlim(-0.6, len(c.participants) - 0.4)
        ax.set_title(f"{c.name} ({c.unit})", fontsize=9)
        ax.ticklabel_format(axis="y", style="sci", scilimits=(-3, 4), useMathText=True)
        ax.tick_params(axis="y", labelsize=8)
    for ax in list(axes.flat)[len(comparisons):]:
        ax.set_visible(False)
    fig.suptitle(title or "benches compared: value +- U (k = 2); red: |E_n| > 1 against every "
                          "other bench, orange: against some", fontsize=10)
    fig.tight_layout()
    return save_figure(fig, path)
