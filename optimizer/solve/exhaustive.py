"""Exhaustive enumeration: the independent oracle and ``--method exact``.

The model already computed every metric of every (propeller, motor, battery)
combination exactly; enumeration is one vectorised masked ``argmin`` over the
cost array. It returns the optimal cost value; the tie-break on the set of
designs that reach it is shared with the MILP (``optimizer.solve.selection``).
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class SolveOutcome:
    """What a selection method found for one grid (indices are flat, C order)."""

    index: int | None
    value: float
    status: str
    solve_time_s: float
    n_candidates: int
    mip_gap: float | None = None
    dual_bound: float | None = None
    detail: str = ""


def solve(cost: np.ndarray, feasible: np.ndarray) -> SolveOutcome:
    """Minimum of ``cost`` over ``feasible`` (both shape (P, M, B)); NaN costs excluded."""
    start = time.perf_counter()
    flat = np.asarray(cost, float).ravel()
    ok = np.asarray(feasible, bool).ravel() & np.isfinite(flat)
    n = int(np.count_nonzero(ok))
    if n == 0:
        return SolveOutcome(None, np.nan, "infeasible", time.perf_counter() - start, 0)
    masked = np.where(ok, flat, np.inf)
    index = int(np.argmin(masked))
    elapsed = time.perf_counter() - start
    return SolveOutcome(index, float(flat[index]), "optimal", elapsed, n)
