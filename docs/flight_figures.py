"""Figures and the ranking table of docs/flight.md and the README's flight section.

Writes docs/img/fly_roll_step.png (10 deg roll steps of thesis-e's Case I design and of
the fastest design that can hover, N = 4, like Paper B's Fig. B.6) and
docs/img/fly_ranking.png (time constant vs closed-loop roll rise time, every feasible
N = 4 design), and prints the ranking table in Markdown: datasheet model, and with
``--measured DIR`` (e.g. ``demo-out`` after ``make demo``) the measured constants too.

    .venv/bin/python docs/flight_figures.py [--measured demo-out]
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np

from bench.figures.fly_figures import pyplot
from bench.store.measured_constants import load_measured_set
from optimizer.catalogs.catalog import load_catalog
from optimizer.flight.design import gains_for, setup
from optimizer.flight.maneuvers import MANEUVERS, fly
from optimizer.model.design_model import evaluate_grid
from optimizer.solve.objectives import single
from optimizer.solve.selection import optimize
from optimizer.sweep.ranking import rank

ROOT = Path(__file__).resolve().parents[1]
IMG = ROOT / "docs" / "img"
CATALOG = ROOT / "optimizer" / "data" / "catalogs" / "thesis-e"


def _key(r) -> str:
    return f"{r.propeller}+{r.motor}+{r.battery}"


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--measured", type=Path, default=None, metavar="DIR")
    args = p.parse_args()
    catalog = load_catalog(CATALOG)
    grid = evaluate_grid(catalog, 4)
    model = rank(catalog, grid)
    measured = None
    if args.measured is not None:
        mset = load_measured_set(args.measured, catalog, None)
        measured = rank(catalog, mset.build_grid(catalog, 4, 0.0))

    best = optimize(catalog, single("flight-time"), (4,)).best
    fastest = min((r for r in model.rows if not r.note), key=lambda r: r.time_constant_ms)
    plt = pyplot()
    IMG.mkdir(parents=True, exist_ok=True)
    fig, (ax1, ax2) = plt.subplots(2, 1, figsize=(7, 5.5), sharex=True)
    for label, (pid, mid, bid) in (
            ("Case I best", (best.propeller, best.motor, best.battery)),
            ("fastest that hovers", (fastest.propeller, fastest.motor, fastest.battery))):
        index = (grid.propeller_ids.index(pid), grid.motor_ids.index(mid),
                 grid.battery_ids.index(bid))
        vehicle, actuator = setup(catalog, grid, index)
        f = fly(vehicle, actuator, MANEUVERS["roll_step"], gains=gains_for(actuator))
        tag = f"{label}: {pid}+{mid}+{bid}, tau {actuator.tau_mean_s * 1e3:.0f} ms"
        ax1.plot(f.t, np.degrees(f.euler[:, 0]), label=tag)
        rpm = 60.0 / (2.0 * math.pi)
        ax2.plot(f.t, (f.omega[:, 0] - f.omega[0, 0]) * rpm, label=f"{label}: rotor 1")
    ax1.plot(f.t, np.degrees(f.setpoint), "k--", lw=0.8, label="setpoint")
    ax1.set_ylabel("roll (deg)")
    ax1.set_title("thesis-e, N = 4: 10 deg roll step, gains from the rule")
    ax1.legend(loc="lower right", fontsize=8)
    ax2.set_ylabel("rotor 1 speed change (rpm)")
    ax2.set_xlabel("time (s)")
    ax2.legend(loc="best", fontsize=8)
    for ax in (ax1, ax2):
        ax.grid(True, alpha=0.3)
    fig.tight_layout()
    fig.savefig(IMG / "fly_roll_step.png", dpi=100)
    plt.close(fig)

    fig, ax = plt.subplots(figsize=(6.5, 4.5))
    for name, r, marker in (("datasheet model", model, "o"), ("measured (demo)", measured, "s")):
        if r is None:
            continue
        ok = [x for x in r.rows if not x.note]
        ax.scatter([x.time_constant_ms for x in ok], [x.rise_time_ms for x in ok], s=16,
                   marker=marker, label=f"{name}: rho {r.rho:.3f} ({len(ok)} designs)")
    ax.set_xlabel("time constant (ms)")
    ax.set_ylabel("closed-loop roll rise time 10-90 % (ms)")
    ax.set_title("thesis-e, N = 4: does the time constant rank closed-loop flight?")
    ax.grid(True, alpha=0.3)
    ax.legend(loc="best", fontsize=8)
    fig.tight_layout()
    fig.savefig(IMG / "fly_ranking.png", dpi=100)
    plt.close(fig)

    other = {_key(r): r for r in measured.rows} if measured is not None else {}
    head = "| design | tau model (ms) | rise model (ms) | overshoot (%) |"
    line = "| --- | ---: | ---: | ---: |"
    if measured is not None:
        head += " tau measured (ms) | rise measured (ms) |"
        line += " ---: | ---: |"
    print(head)
    print(line)

    def cell(x: float | None) -> str:
        return "-" if x is None else f"{x:.0f}"

    for r in sorted(model.rows, key=lambda r: r.time_constant_ms):
        row = (f"| {_key(r)} | {r.time_constant_ms:.1f} | "
               f"{cell(r.rise_time_ms) if not r.note else r.note} | {r.overshoot_pct:.1f} |")
        if measured is not None:
            m = other.get(_key(r))
            row += (" infeasible (measured) | - |" if m is None else
                    f" {m.time_constant_ms:.1f} | {cell(m.rise_time_ms)} |")
        print(row)
    print(f"\nSpearman rho, datasheet model: {model.rho:.3f} ({model.n_ranked} designs, "
          f"p = {model.p_value:.1e})")
    if measured is not None:
        print(f"Spearman rho, measured: {measured.rho:.3f} ({measured.n_ranked} designs, "
              f"p = {measured.p_value:.1e})")


if __name__ == "__main__":
    main()
