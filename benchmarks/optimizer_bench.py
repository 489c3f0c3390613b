"""Optimizer benchmark: solve times of the exact MILP, enumeration and Paper E's MILP.

Prints three tables (measured on this machine, nothing hard-coded):
1. Paper E's test cases I-III (thesis-e catalog) x actuator counts: the default
   MILP's solve time (target < 0.2 s each), enumeration, and the thesis
   formulation (``optimizer.solve.thesis_formulation``) beside it, with their choices.
2. A generated, seeded, physically plausible catalog of 200 propellers x 150
   motors x 40 batteries: per actuator count the grid build, MILP and
   enumeration times, their ratio and whether they agree (targets: MILP < 10 s,
   enumeration < 5 s); plus the three MILP formulations on a medium catalog.
3. The SizingLab catalogs (optimizer/data/sizinglab, imported in memory).

Run: ``.venv/bin/python benchmarks/optimizer_bench.py [--quick]``.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd
from rich.console import Console
from rich.table import Table

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from optimizer.catalogs.catalog import Catalog, load_catalog  # noqa: E402
from optimizer.model.design_model import evaluate_grid  # noqa: E402
from optimizer.solve import exhaustive, milp_exact  # noqa: E402
from optimizer.solve.objectives import single  # noqa: E402
from optimizer.solve.selection import Requirements, optimize, select_from_grids  # noqa: E402

PAPER_E_CASES = (
    ("I", "flight-time", 0.0),
    ("II", "flight-time", 1.5),
    ("III", "time-constant", 0.0),
)
ACTUATORS = (4, 6, 8)


def generated_catalog(seed: int, n_p: int, n_m: int, n_b: int) -> Catalog:
    """Seeded random catalog with datasheet-like relations between the columns.

    Propellers 7-24 in (mass ~ D^2.3, Ct 0.08-0.14, Cp/Ct 0.45-0.75); motors
    sized by stator mass 25-450 g (Kv falls and current rises with size,
    resistance falls); 3S-6S LiPo packs of 1-22 Ah at 130-190 Wh/kg, 20-60 C.
    """
    rng = np.random.default_rng(seed)
    d_in = rng.uniform(7, 24, n_p)
    ct = rng.uniform(0.08, 0.14, n_p)
    props = pd.DataFrame(
        {
            "id": [f"P{i + 1}" for i in range(n_p)],
            "name": [f"gen {d:.1f} in" for d in d_in],
            "mass_g": np.round(0.16 * d_in**2.3 / 10 * rng.uniform(0.8, 1.25, n_p), 1),
            "diameter_m": np.round(d_in * 0.0254, 4),
            "ct": np.round(ct, 4),
            "cp": np.round(ct * rng.uniform(0.45, 0.75, n_p), 4),
            "price": np.round(1.5 + 0.35 * d_in * rng.uniform(0.7, 1.4, n_p), 2),
        }
    )
    size = rng.uniform(25, 450, n_m)  # g
    motors = pd.DataFrame(
        {
            "id": [f"M{i + 1}" for i in range(n_m)],
            "name": [f"gen {s:.0f} g" for s in size],
            "kv_rpm_per_v": np.round(9000 / np.sqrt(size) * rng.uniform(0.6, 1.5, n_m)),
            "resistance_ohm": np.round(4.0 / size * rng.uniform(0.6, 1.6, n_m), 4),
            "mass_g": np.round(size, 1),
            "max_current_a": np.round(0.12 * size * rng.uniform(0.8, 1.3, n_m), 1),
            "max_power_w": np.round(2.2 * size * rng.uniform(0.8, 1.3, n_m)),
            "price": np.round(12 + 0.12 * size * rng.uniform(0.7, 1.5, n_m), 2),
        }
    )
    cells = rng.integers(3, 7, n_b)
    cap = np.round(rng.uniform(1000, 22000, n_b), -2)
    energy_wh = cap / 1000 * 3.7 * cells
    batteries = pd.DataFrame(
        {
            "id": [f"B{i + 1}" for i in range(n_b)],
            "name": [f"gen {c}S {a:.0f} mAh" for c, a in zip(cells, cap, strict=True)],
            "mass_g": np.round(energy_wh / rng.uniform(130, 190, n_b) * 1000, 1),
            "capacity_mah": cap,
            "cells": cells,
            "price": np.round(energy_wh * rng.uniform(0.5, 1.0, n_b), 2),
            "c_rating": rng.choice([20, 25, 30, 40, 50, 60], n_b),
        }
    )
    constants = {"min_thrust_to_weight": 2.0, "battery_voltage": "nominal"}
    return Catalog.from_frames(
        props, motors, batteries, constants, source=f"generated(seed={seed})"
    )


def _ids(d) -> str:
    return f"{d.propeller}/{d.motor}/{d.battery}" if d.feasible else "infeasible"


def paper_e_table(console: Console) -> None:
    from optimizer.solve.thesis_formulation import solve_thesis

    catalog = load_catalog(REPO / "optimizer" / "data" / "catalogs" / "thesis-e")
    table = Table(title="Paper E test cases, thesis-e catalog", title_justify="left")
    for col in (
        "case",
        "N",
        "MILP design",
        "MILP s",
        "enum s",
        "thesis design",
        "thesis s",
        "thesis shortfall",
        "< 0.2 s",
    ):
        table.add_column(col, justify="right")
    for case, objective, payload in PAPER_E_CASES:
        req = Requirements(payload_kg=payload)
        by_milp = optimize(catalog, single(objective), ACTUATORS, req, "milp")
        by_enum = optimize(catalog, single(objective), ACTUATORS, req, "exact")
        for d, e in zip(by_milp.designs, by_enum.designs, strict=True):
            th = solve_thesis(catalog, d.actuators, objective, payload)
            thesis_ids = f"{th.propeller}/{th.motor}/{th.battery}" if th.propeller else "-"
            short = "-" if th.shortfall is None else f"{100 * th.shortfall:.2f} %"
            mark = " *" if by_milp.best is d else ""
            assert _ids(d) == _ids(e), "MILP and enumeration disagree"
            table.add_row(
                case,
                f"{d.actuators}{mark}",
                _ids(d),
                f"{d.solve_time_s:.4f}",
                f"{e.solve_time_s:.5f}",
                thesis_ids,
                f"{th.solve_time_s:.3f}",
                short,
                "yes" if d.solve_time_s < 0.2 else "NO",
            )
    console.print(table)
    console.print(
        "* = best actuator count; thesis shortfall = loss of the thesis formulation's "
        "choice against the exact optimum on the stated objective."
    )


def large_table(console: Console, seed: int, shape: tuple[int, int, int], payload: float) -> None:
    catalog = generated_catalog(seed, *shape)
    title = (
        f"Generated catalog {shape[0]} x {shape[1]} x {shape[2]} (seed {seed}), "
        f"max flight time, payload {payload} kg"
    )
    table = Table(title=title, title_justify="left")
    for col in (
        "N",
        "designs",
        "feasible",
        "grid s",
        "MILP s",
        "gap",
        "no-cutoff s",
        "enum s",
        "MILP/enum",
        "agree",
        "design",
        "flight min",
        "< 10 s / < 5 s",
    ):
        table.add_column(col, justify="right")
    objective = single("flight-time")
    req = Requirements(payload_kg=payload)
    for n in ACTUATORS:
        t0 = time.perf_counter()
        grid = evaluate_grid(catalog, n, payload)
        t_grid = time.perf_counter() - t0
        a = select_from_grids([grid], objective, req, "milp").designs[0]
        b = select_from_grids([grid], objective, req, "exact").designs[0]
        c = select_from_grids([grid], objective, req, "milp", milp_options={"cutoff": False})
        c = c.designs[0]
        enum_total = t_grid + b.solve_time_s  # enumeration = exact evaluation + argmin
        agree = _ids(a) == _ids(b) == _ids(c)
        table.add_row(
            str(n),
            f"{a.n_designs:,}",
            f"{a.n_candidates:,}",
            f"{t_grid:.2f}",
            f"{a.solve_time_s:.2f}",
            f"{a.mip_gap}",
            f"{c.solve_time_s:.2f}",
            f"{enum_total:.2f}",
            f"{a.solve_time_s / enum_total:.1f}",
            "yes" if agree else "NO",
            _ids(a),
            f"{a.metrics.get('flight_time_min', float('nan')):.1f}",
            f"{'yes' if a.solve_time_s < 10 else 'NO'} / {'yes' if enum_total < 5 else 'NO'}",
        )
    console.print(table)
    console.print(
        "enum s = building the exact grid + vectorised argmin (the oracle's whole "
        "cost); MILP s (default, objective cutoff) and no-cutoff s (block MILP over every "
        "feasible combination) exclude the shared grid build."
    )


def formulation_table(console: Console, seed: int, shape: tuple[int, int, int]) -> None:
    catalog = generated_catalog(seed, *shape)
    grid = evaluate_grid(catalog, 4, 0.5)
    cost = single("flight-time").cost(grid)
    ok = grid.feasible() & np.isfinite(cost)
    ref = exhaustive.solve(cost, ok)
    table = Table(
        title=f"MILP formulations, {shape[0]} x {shape[1]} x {shape[2]}, "
        f"{int(ok.sum()):,} feasible combinations (4 actuators)",
        title_justify="left",
    )
    for col in ("formulation", "binaries", "solve s", "status", "gap", "same optimum"):
        table.add_column(col, justify="right")
    binaries = {
        "block": len(np.unique(np.nonzero(ok)[2])),
        "unit": int(ok.sum()),
        "factored": sum(len(np.unique(a)) for a in np.nonzero(ok)),
    }
    for form in ("block", "unit", "factored"):
        out = milp_exact.solve(cost, ok, formulation=form, time_limit_s=60)
        table.add_row(
            form,
            f"{binaries[form]:,}",
            f"{out.solve_time_s:.2f}",
            out.status,
            f"{out.mip_gap}",
            "yes" if out.value == ref.value else "NO",
        )
    console.print(table)


def scaling_table(console: Console, seed: int) -> None:
    """How the unit and block formulations grow with the number of combinations."""
    rng = np.random.default_rng(seed)
    table = Table(title="Formulation scaling on random costs (40 batteries)", title_justify="left")
    for col in ("combinations", "block s", "unit s", "same optimum"):
        table.add_column(col, justify="right")
    for n in (5_000, 10_000, 20_000):
        cost = rng.normal(50.0, 10.0, (n // 40, 1, 40))
        ok = np.ones(cost.shape, bool)
        a = milp_exact.solve(cost, ok, formulation="block")
        b = milp_exact.solve(cost, ok, formulation="unit")
        table.add_row(
            f"{n:,}",
            f"{a.solve_time_s:.2f}",
            f"{b.solve_time_s:.2f}",
            "yes" if a.value == b.value else "NO",
        )
    console.print(table)


def sizinglab_table(console: Console) -> None:
    from optimizer.catalogs.sizinglab import DEFAULT_FOLDER, import_sizinglab

    folder = Path(os.environ.get("ROTORBENCH_SIZINGLAB", DEFAULT_FOLDER))
    if not folder.is_dir():
        console.print(f"SizingLab data not found at {folder}; skipped")
        return
    t0 = time.perf_counter()
    catalog = import_sizinglab(folder)
    t_import = time.perf_counter() - t0
    shape = (len(catalog.propellers), len(catalog.motors), len(catalog.batteries))
    table = Table(
        title=f"SizingLab catalogs {shape[0]} x {shape[1]} x {shape[2]} (import {t_import:.2f} s)",
        title_justify="left",
    )
    for col in (
        "objective",
        "payload kg",
        "N",
        "feasible",
        "MILP s",
        "enum s",
        "agree",
        "design",
        "flight min",
        "tau ms",
        "price",
    ):
        table.add_column(col, justify="right")
    for objective, payload in (("flight-time", 1.0), ("time-constant", 1.0), ("price", 2.0)):
        req = Requirements(payload_kg=payload, min_flight_time_min=10.0)
        a = optimize(catalog, single(objective), ACTUATORS, req, "milp")
        b = optimize(catalog, single(objective), ACTUATORS, req, "exact")
        for d, e in zip(a.designs, b.designs, strict=True):
            mark = " *" if a.best is d else ""
            m = d.metrics
            table.add_row(
                objective,
                f"{payload}",
                f"{d.actuators}{mark}",
                f"{d.n_candidates:,}",
                f"{d.solve_time_s:.3f}",
                f"{d.grid_time_s + e.solve_time_s:.3f}",
                "yes" if _ids(d) == _ids(e) else "NO",
                _ids(d),
                f"{m.get('flight_time_min', float('nan')):.1f}",
                f"{m.get('time_constant_ms', float('nan')):.0f}",
                f"{m.get('price', float('nan')):.0f}",
            )
    console.print(table)
    console.print(
        "requirement: flight time >= 10 min; prices are the importer's assumptions "
        "(docs/optimizer.md)."
    )


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="a 60 x 50 x 20 catalog instead")
    parser.add_argument("--seed", type=int, default=2026)
    args = parser.parse_args()
    console = Console(width=160)
    console.print(
        f"numpy {np.__version__}, scipy {__import__('scipy').__version__}, {os.cpu_count()} CPUs"
    )
    paper_e_table(console)
    large = (60, 50, 20) if args.quick else (200, 150, 40)
    large_table(console, args.seed, large, 1.0)
    formulation_table(console, args.seed, (30, 25, 12))
    scaling_table(console, args.seed)
    sizinglab_table(console)
    return 0


if __name__ == "__main__":
    sys.exit(main())
