"""Cells in series and parallel: the optimizer chooses S and P (thesis section 3.2, future work).

A battery catalog is read as a cell catalog: a row of ``cells`` cells is that many cells
of one string (1P), so one cell has the row's capacity and current limit, 1/S of its
mass, price, nominal voltage and resistance. An SxP pack of a cell has S times the cell
voltage (``cells = S``: the model's B_V, its current (E.67) and every voltage-dependent
limit and rule follow), P times its capacity and current limit, S P times its mass and
price, and resistance S R_cell / P. Identical cells are listed once.

Every (cell, S, P) becomes one battery of the design grid, so selection stays the exact
choice of ``optimizer.solve.selection`` (MILP or enumeration over precomputed designs). To keep
memory bounded, :func:`optimize_packs` solves one grid per series count S (decomposition
by battery voltage, section 4.2 of the project's notes reference/design-optimization.md,
not shipped) and carries the best cost found so far as an objective cutoff into the next S
(designs costlier than it cannot be optimal; equal ones stay for the tie-break). The winner
across S is chosen by cost, then the shared tie order, then the lower S.
"""

from __future__ import annotations

import math
import re
import time
from collections.abc import Callable, Sequence

import numpy as np
import pandas as pd

from optimizer.catalogs.catalog import Catalog
from optimizer.errors import RequestError
from optimizer.model.grid import DesignGrid
from optimizer.solve.objectives import Objective
from optimizer.solve.selection import (
    TIE_ORDER,
    DesignResult,
    Requirements,
    SelectionResult,
    _tol,
    lexicographic_pick,
    pick_best,
    select_from_grids,
)


def parse_counts(text: str, what: str, low: int = 1) -> tuple[int, ...]:
    """'2-6', '3' or '2,4,6' as a tuple of whole numbers >= ``low``."""
    out: list[int] = []
    for part in filter(None, (p.strip() for p in str(text).split(","))):
        m = re.fullmatch(r"(\d+)(?:-(\d+))?", part)
        if not m:
            raise RequestError(f"{what}: expected counts like 2-6, 3 or 2,4; got {text!r}")
        a, b = int(m.group(1)), int(m.group(2) or m.group(1))
        if a > b:
            raise RequestError(f"{what}: empty range {part!r}")
        out += range(a, b + 1)
    if not out or min(out) < low:
        raise RequestError(f"{what}: expected whole numbers >= {low}, got {text!r}")
    return tuple(dict.fromkeys(out))


def cells_of(catalog: Catalog) -> pd.DataFrame:
    """One row per distinct cell of the catalog's batteries (SI, per cell)."""
    b = catalog.batteries
    s = b["cells"].to_numpy(float)
    volt = b["nominal_voltage_v"].to_numpy(float) / s
    volt = np.where(np.isnan(volt), catalog.constants.cell_voltage_nominal_v, volt)
    cells = pd.DataFrame({
        "id": b["id"].to_numpy(),
        "name": b["name"].to_numpy(),
        "mass_kg": b["mass_kg"].to_numpy(float) / s,
        "capacity_ah": b["capacity_ah"].to_numpy(float),
        "price": b["price"].to_numpy(float) / s,
        "max_current_a": b["max_current_a"].to_numpy(float),
        "c_rating": b["c_rating"].to_numpy(float),
        "burst_c_rating": b["burst_c_rating"].to_numpy(float),
        "voltage_v": volt,
        "resistance_ohm": b["resistance_ohm"].to_numpy(float) / s,
    })
    dup = cells.drop(columns=["id", "name"]).round(12).fillna(-1.0).duplicated()
    return cells.loc[~dup.to_numpy()].reset_index(drop=True)


def pack_frame(cells: pd.DataFrame, series: Sequence[int], parallel: Sequence[int]
               ) -> pd.DataFrame:
    """Battery rows (SI, catalog columns) for every (cell, S, P), cells fastest."""
    c = len(cells)
    s = np.repeat(np.asarray(series, float), len(parallel) * c)
    p = np.tile(np.repeat(np.asarray(parallel, float), c), len(series))
    idx = np.tile(np.arange(c), len(series) * len(parallel))
    cell = cells.iloc[idx].reset_index(drop=True)
    sp = s * p
    ids = [f"{i}-{int(a)}S{int(b)}P" for i, a, b in zip(cell["id"], s, p, strict=True)]
    return pd.DataFrame({
        "id": ids,
        "name": [f"{int(a)}S{int(b)}P of {n}" for n, a, b in zip(cell["name"], s, p,
                                                                 strict=True)],
        "mass_kg": sp * cell["mass_kg"].to_numpy(),
        "capacity_ah": p * cell["capacity_ah"].to_numpy(),
        "cells": s,
        "price": sp * cell["price"].to_numpy(),
        "max_current_a": p * cell["max_current_a"].to_numpy(),
        "c_rating": cell["c_rating"].to_numpy(),
        "nominal_voltage_v": s * cell["voltage_v"].to_numpy(),
        "burst_c_rating": cell["burst_c_rating"].to_numpy(),
        "resistance_ohm": s * cell["resistance_ohm"].to_numpy() / p,
        "series": s.astype(int),
        "parallel": p.astype(int),
        "cell": cell["id"].to_numpy(),
    })


def with_packs(catalog: Catalog, series: Sequence[int], parallel: Sequence[int]) -> Catalog:
    """The catalog with its batteries replaced by every SxP pack of its cells."""
    packs = pack_frame(cells_of(catalog), series, parallel)
    return Catalog(catalog.propellers, catalog.motors, packs, catalog.constants,
                   f"{catalog.source} (cells {min(series)}-{max(series)}S "
                   f"{min(parallel)}-{max(parallel)}P)")


def packs_at(catalog: Catalog, cells: pd.DataFrame, series: int,
             parallel: Sequence[int]) -> Catalog:
    """The catalog whose batteries are the packs of ``cells`` at one series count (the
    catalog of one per-S grid: :func:`optimize_packs`, the flight sweep)."""
    return Catalog(catalog.propellers, catalog.motors, pack_frame(cells, (series,), parallel),
                   catalog.constants, catalog.source)


def optimize_packs(
    catalog: Catalog,
    objective: Objective,
    actuators: Sequence[int],
    requirements: Requirements | None = None,
    method: str = "milp",
    series: Sequence[int] = (2, 3, 4, 5, 6),
    parallel: Sequence[int] = (1, 2, 3, 4),
    *,
    build_grid: Callable[[Catalog, int, float], DesignGrid] | None = None,
) -> SelectionResult:
    """Best design per actuator count with the pack's S and P chosen too (exact)."""
    if not objective.is_single:
        raise RequestError("series/parallel selection takes a single objective (weighted sums "
                           "normalise over all designs, which the per-S decomposition splits)")
    if method not in ("milp", "exact"):
        raise RequestError("series/parallel selection works with --method milp or exact")
    req = (requirements or Requirements()).validate()
    if build_grid is None:
        from optimizer.model.design_model import evaluate_grid as build_grid
    cells = cells_of(catalog)
    designs: list[DesignResult] = []
    for n in dict.fromkeys(actuators):
        per_s: list[DesignResult] = []
        incumbent = math.inf
        for s in series:
            sub = packs_at(catalog, cells, s, parallel)
            packs = sub.batteries
            start = time.perf_counter()
            grid = build_grid(sub, n, req.payload_kg)
            gtime = time.perf_counter() - start
            cut = _Cutoff(grid, objective, incumbent)
            if not cut.any_left:
                continue  # nothing at this S reaches the incumbent: no solve, no explanation
            res = select_from_grids([cut.grid], objective, req, method, grid_times=[gtime],
                                    source=catalog.source).designs[0]
            if res.feasible:
                assert res.index is not None  # a feasible design has its grid index
                row = packs.iloc[res.index[2]]
                res.extra.update({"series": int(row["series"]), "parallel": int(row["parallel"]),
                                  "cell": str(row["cell"])})
                incumbent = min(incumbent, res.cost)
                per_s.append(res)
            elif not per_s and s == series[-1]:
                per_s.append(res)  # nothing feasible at any S: report the last reason
        designs.append(_best_over_s(per_s, n))
    return SelectionResult(objective, method, req, designs, pick_best(designs),
                           f"{catalog.source} (S {','.join(map(str, series))}, "
                           f"P {','.join(map(str, parallel))})")


class _Cutoff:
    """A grid whose designs costlier than ``incumbent`` (+ tie tolerance) fail a check."""

    def __init__(self, grid: DesignGrid, objective: Objective, incumbent: float) -> None:
        from dataclasses import replace

        from optimizer.model.grid import Check

        self.any_left = True
        if not math.isfinite(incumbent):
            self.grid = grid
            return
        cost = np.nan_to_num(objective.cost(grid), nan=np.inf)
        limit = incumbent + _tol(incumbent, abs(incumbent))
        self.any_left = bool(np.any(cost <= limit))
        check = Check("cost cutoff (better design at another S)", "", cost, np.asarray(limit))
        self.grid = replace(grid, checks=(*grid.checks, check))


def _best_over_s(per_s: list[DesignResult], n: int) -> DesignResult:
    ok = [d for d in per_s if d.feasible]
    if not ok:
        return per_s[-1] if per_s else DesignResult(
            actuators=n, feasible=False, index=None, propeller=None, motor=None, battery=None,
            metrics={}, cost=math.nan, solve_time_s=0.0, grid_time_s=0.0, method="",
            status="infeasible", n_candidates=0, n_designs=0, reason="no series count given")
    costs = np.array([d.cost for d in ok])
    best = float(costs.min())
    scale = float(np.mean(np.abs(costs)))
    tied = [d for d, c in zip(ok, costs, strict=True) if c <= best + _tol(best, scale)]
    order = np.array([d.extra["series"] for d in tied])
    cols = [(np.array([d.metrics.get(m, math.nan) for d in tied]), sense)
            for m, sense in TIE_ORDER]
    win = tied[lexicographic_pick(order, cols)]
    win.solve_time_s = sum(d.solve_time_s for d in per_s)
    win.grid_time_s = sum(d.grid_time_s for d in per_s)
    return win
