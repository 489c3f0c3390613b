"""Time the design model: catalog validation and evaluate_grid on 200 x 150 x 40 designs.

Prints measured wall-clock times (best and median of several runs) on this machine.
"""

from __future__ import annotations

import statistics
import time

import numpy as np
import pandas as pd
from rich.console import Console
from rich.table import Table

from optimizer.catalogs.catalog import Catalog
from optimizer.model.design_model import evaluate_grid

SIZES = (200, 150, 40)
REPEATS = 7


def synthetic_frames(n_p: int, n_m: int, n_b: int, seed: int = 0):
    """Plausible random datasheet frames (CSV column names and units)."""
    rng = np.random.default_rng(seed)
    props = pd.DataFrame(
        {
            "id": [f"P{i}" for i in range(n_p)],
            "name": "prop",
            "mass_g": rng.uniform(5, 40, n_p),
            "diameter_m": rng.uniform(0.15, 0.45, n_p),
            "ct": rng.uniform(0.08, 0.14, n_p),
            "cp": rng.uniform(0.04, 0.09, n_p),
            "price": rng.uniform(2, 20, n_p),
        }
    )
    motors = pd.DataFrame(
        {
            "id": [f"M{i}" for i in range(n_m)],
            "name": "motor",
            "kv_rpm_per_v": rng.uniform(300, 3000, n_m),
            "resistance_ohm": rng.uniform(0.02, 0.3, n_m),
            "mass_g": rng.uniform(30, 200, n_m),
            "max_current_a": rng.uniform(10, 60, n_m),
            "max_power_w": rng.uniform(100, 800, n_m),
            "price": rng.uniform(10, 80, n_m),
            "inertia_kgm2": rng.uniform(5e-6, 5e-5, n_m),
        }
    )
    batteries = pd.DataFrame(
        {
            "id": [f"B{i}" for i in range(n_b)],
            "name": "battery",
            "mass_g": rng.uniform(100, 1500, n_b),
            "capacity_mah": rng.uniform(1000, 16000, n_b),
            "cells": rng.integers(2, 7, n_b),
            "price": rng.uniform(10, 120, n_b),
            "c_rating": rng.uniform(10, 50, n_b),
        }
    )
    return props, motors, batteries


def timed(fn, repeats: int = REPEATS) -> tuple[float, float]:
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return min(times), statistics.median(times)


def main() -> None:
    frames = synthetic_frames(*SIZES)
    catalog = Catalog.from_frames(*frames)
    table = Table(
        title=f"design model on {SIZES[0]} x {SIZES[1]} x {SIZES[2]} = "
        f"{np.prod(SIZES):,} designs ({REPEATS} runs)"
    )
    table.add_column("step")
    table.add_column("best [s]", justify="right")
    table.add_column("median [s]", justify="right")
    best, median = timed(lambda: Catalog.from_frames(*frames))
    table.add_row("Catalog.from_frames (validate + SI)", f"{best:.4f}", f"{median:.4f}")
    for n in (4, 6, 8):
        best, median = timed(lambda n=n: evaluate_grid(catalog, n, 0.5))
        table.add_row(f"evaluate_grid, N = {n}", f"{best:.4f}", f"{median:.4f}")
    Console().print(table)


if __name__ == "__main__":
    main()
