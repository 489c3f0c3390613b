"""Cost of the robust-design draws (optimizer.flight.uncertainty) against the flights.

A sweep with ``--samples M`` draws the measured constants of every design M times before
flying them. This prints, for D designs x M samples (default 100 000 x 20, every design
with a spread on all five constants): the time of the per-design seeds (SHA-256 +
SeedSequence), of the draws (one PCG64 per design, then vectorised transforms) and of
the 5/50/95 percentiles of one figure, and as the yardstick the CPU time of one 4 s
``roll_step`` flight of thesis-e's Case I design. The ratio says how many flights the
draws of one design cost.

    .venv/bin/python benchmarks/uncertainty_draws.py [--designs 100000] [--samples 20]
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable
from typing import Any

import numpy as np

from optimizer.catalogs.catalog import load_catalog
from optimizer.flight.design import gains_for, setup
from optimizer.flight.maneuvers import MANEUVERS, fly
from optimizer.flight.uncertainty import (
    QUANTITIES,
    design_seeds,
    draw_many,
    percentile_columns,
)
from optimizer.model.design_model import evaluate_grid

CATALOG = "optimizer/data/catalogs/thesis-e"
NOMINAL = (0.040, 0.060, 0.012, 1.2e-6, 2.0e-8)
STD = (0.004, 0.009, 0.002, 3e-8, 1e-9)


def cpu(fn: Callable[[], Any]) -> tuple[float, Any]:
    """CPU seconds of ``fn()`` and what it returned."""
    start = time.process_time()
    out = fn()
    return time.process_time() - start, out


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--designs", type=int, default=100_000)
    p.add_argument("--samples", type=int, default=20)
    args = p.parse_args()
    d, m = args.designs, args.samples
    designs = [{"actuators": 4, "propeller": f"P{i % 50}", "motor": f"M{i // 50 % 40}",
                "battery": f"B{i // 2000}", "series": 3 + i % 3, "parallel": 1}
               for i in range(d)]
    nominal = {q: np.full(d, v) for q, v in zip(QUANTITIES, NOMINAL, strict=True)}
    std = {q: np.full(d, v) for q, v in zip(QUANTITIES, STD, strict=True)}
    t_seed, seeds = cpu(lambda: design_seeds(designs, seed=1))
    t_draw, draws = cpu(lambda: draw_many(nominal, std, m, seeds))
    figure = draws["tau_up_s"] * 1e4  # any (designs, samples) figure
    figure[:, 3] = np.nan  # a sample that never rose
    t_pct, _ = cpu(lambda: percentile_columns("roll_rise_time_ms", figure))
    print(f"{d} designs x {m} samples, CPU: seeds {t_seed:.2f} s, draws {t_draw:.2f} s, "
          f"percentiles {t_pct:.3f} s; {(t_seed + t_draw) / d * 1e6:.1f} us per design")

    catalog = load_catalog(CATALOG)
    grid = evaluate_grid(catalog, 4)
    index = (grid.propeller_ids.index("P4"), grid.motor_ids.index("M1"),
             grid.battery_ids.index("B3"))
    vehicle, actuator = setup(catalog, grid, index)
    gains = gains_for(actuator)
    t_fly = min(cpu(lambda: fly(vehicle, actuator, MANEUVERS["roll_step"], gains=gains,
                                record=False))[0] for _ in range(3))
    per_design = (t_seed + t_draw) / d
    print(f"one roll_step flight ({MANEUVERS['roll_step'].duration_s:g} s): {t_fly:.3f} s "
          f"CPU; the draws of one design cost {per_design / (m * t_fly) * 100:.4f} % of "
          f"its {m} flights")


if __name__ == "__main__":
    main()
