"""The default, exact MILP: choose one precomputed (propeller, motor, battery) design.

Why it is exact: the components are discrete, so the model computes every
nonlinear quantity (hover speed, power, current, flight time, time constant,
inertias) exactly for each combination. The MILP never approximates physics;
it only chooses, and every metric of a combination is a constant coefficient.

Before building, combinations that violate a physical limit or a requirement
(or whose cost is not finite) are dropped: they can never be chosen, so no
constraint row is needed for them. This is how every per-combination constraint
is written, the hover margin (full-throttle thrust-to-weight ``TW_c >= R``, the
sizing commands' default) included: ``(TW_c - R) u_c >= 0`` with ``u_c`` the
combination's 0/1 choice is ``u_c = 0`` where ``TW_c < R``, i.e. the column is
fixed to zero, which presolve would do anyway. An aggregate row
``sum_c TW_c u_c >= R`` would not be equivalent in the block formulation, whose
weights are continuous: a mix of designs could meet it. Three formulations of the choice
(``docs/optimizer.md`` has the measured times):

``block`` (default)
    one binary ``z_b`` per battery that has a surviving combination, a row
    ``sum z = 1``, and one continuous weight ``0 <= u_pmb <= 1`` per surviving
    combination with the linking rows ``sum_{p,m} u_pmb = z_b``. The
    constraint matrix is a network matrix (totally unimodular), so the LP
    relaxation is integral: the root LP is the convex hull and HiGHS proves
    optimality at the root node (gap 0) with only B binaries. Linear in the
    number of combinations; fastest on large catalogs.
``unit``
    one binary per surviving combination and a single row ``sum x = 1``.
    Same integral LP relaxation, but HiGHS' MIP set-up (clique and symmetry
    detection, presolve) grows much faster than linearly with the number of
    binaries in one set-partitioning row (benchmarks/optimizer_bench.py: 1.3 s
    for 5 k, 4.4 s for 10 k, 17.6 s for 20 k combinations).
``factored``
    binaries per propeller, motor and battery (one-hot rows), plus one
    continuous weight per surviving combination linked by marginal rows
    (``sum_{m,b} u_pmb = x_p`` and likewise for m, b). Equally exact and
    just as tight (the marginals are the convex hull of the product of
    simplices), but it keeps the per-combination columns, because flight
    time and current depend jointly on (p, m, b) through the total mass, and
    adds P + M + B binaries and 3 rows per combination column. It is kept
    for the benchmark, which measures that it is slower.

Objective cutoff (default on large problems, ``cutoff=True``): the block MILP
over every k-th surviving combination (about ``CUTOFF_SAMPLE`` of them) yields an
incumbent of cost ``U``; combinations with cost ``> U`` are dropped, since the
optimum is ``<= U`` (bound-based fixing, as a MIP presolve does with an
incumbent); the MILP over the survivors proves the optimum. Without it, HiGHS
and scipy's wrapper spend 4-7 s per million columns on set-up and presolve.

Costs are divided by their mean magnitude (no shift: the scale must not need
the optimum) and HiGHS runs with ``mip_rel_gap = mip_abs_gap = 0`` and tight
feasibility tolerances, so the returned design is optimal to ~1e-9 relative,
far inside the tie tolerance of ``optimizer.solve.selection``.
"""

from __future__ import annotations

import time
import warnings
from typing import Literal

import numpy as np
from scipy import sparse
from scipy.optimize import Bounds, LinearConstraint, OptimizeResult, milp

from optimizer.solve.exhaustive import SolveOutcome

Formulation = Literal["block", "unit", "factored"]

#: HiGHS options: prove optimality exactly (zero gaps, tight tolerances). Symmetry
#: detection and primal heuristics are off: the root LP of these models is integral, so
#: they only cost time (measured: 6.7 s -> 4.0 s on 947 k combinations).
HIGHS_OPTIONS: dict[str, object] = {
    "mip_rel_gap": 0.0,
    "mip_abs_gap": 0.0,
    "mip_detect_symmetry": False,
    "mip_heuristic_effort": 0.0,
    "dual_feasibility_tolerance": 1e-9,
    "primal_feasibility_tolerance": 1e-9,
}

_STATUS = {0: "optimal", 1: "limit", 2: "infeasible", 3: "unbounded", 4: "other"}


#: Incumbent phase of the objective cutoff: a MILP over every k-th surviving combination.
CUTOFF_SAMPLE = 10_000


def solve(
    cost: np.ndarray,
    feasible: np.ndarray,
    *,
    formulation: Formulation = "block",
    time_limit_s: float = 60.0,
    presolve: bool = True,
    cutoff: bool = True,
) -> SolveOutcome:
    """Minimise ``cost`` over ``feasible`` designs (arrays of shape (P, M, B)) with HiGHS.

    With ``cutoff`` (default) and more than ``2 * CUTOFF_SAMPLE`` surviving
    combinations, the solve has two phases: the same MILP over an evenly strided
    sample gives an incumbent of cost ``U``; every combination with cost ``> U``
    cannot be optimal (objective cutoff, standard bound-based fixing) and is
    dropped; the MILP over the rest proves the optimum. Exact, because the
    optimum is ``<= U``.
    """
    start = time.perf_counter()
    shape = np.shape(cost)
    flat = np.asarray(cost, float).ravel()
    keep = np.flatnonzero(np.asarray(feasible, bool).ravel() & np.isfinite(flat))
    n = keep.size
    if n == 0:
        return SolveOutcome(None, np.nan, "infeasible", time.perf_counter() - start, 0)
    scale = float(np.mean(np.abs(flat[keep]))) or 1.0
    detail = ""
    if cutoff and n > 2 * CUTOFF_SAMPLE:
        sample = keep[:: -(-n // CUTOFF_SAMPLE)]
        res, chosen = _run(flat[sample] / scale, sample, shape, formulation, time_limit_s, presolve)
        if chosen is not None:
            upper = flat[sample[chosen]]
            keep = keep[flat[keep] <= upper]
            detail = f"cutoff at incumbent {upper:.6g}: {keep.size} of {n} combinations kept; "
    res, chosen = _run(flat[keep] / scale, keep, shape, formulation, time_limit_s, presolve)
    elapsed = time.perf_counter() - start
    status = _STATUS.get(int(res.status), "other")
    if chosen is None:
        return SolveOutcome(None, np.nan, status, elapsed, n, detail=detail + str(res.message))
    index = int(keep[chosen])
    gap = getattr(res, "mip_gap", None)
    bound = getattr(res, "mip_dual_bound", None)
    return SolveOutcome(
        index=index,
        value=float(flat[index]),
        status=status,
        solve_time_s=elapsed,
        n_candidates=n,
        mip_gap=None if gap is None else float(gap),
        dual_bound=None if bound is None else float(bound) * scale,
        detail=detail + str(res.message),
    )


def _run(
    c: np.ndarray,
    keep: np.ndarray,
    shape: tuple[int, ...],
    formulation: str,
    time_limit_s: float,
    presolve: bool,
) -> tuple[OptimizeResult, int | None]:
    """One HiGHS solve; returns the result and the chosen position in ``keep``."""
    if formulation == "block":
        c_all, integrality, constraints = _block_model(c, keep, shape)
    elif formulation == "unit":
        c_all, integrality, constraints = _unit_model(c)
    elif formulation == "factored":
        c_all, integrality, constraints = _factored_model(c, keep, shape)
    else:
        raise ValueError(f"unknown formulation {formulation!r}")
    options = {"time_limit": float(time_limit_s), "presolve": presolve, **HIGHS_OPTIONS}
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message="Unrecognized options", category=RuntimeWarning)
        res = milp(
            c_all,
            integrality=integrality,
            bounds=Bounds(0.0, 1.0),
            constraints=constraints,
            options=options,
        )
    if res.x is None:
        return res, None
    return res, int(np.argmax(res.x[: c.size]))


def _block_model(
    c: np.ndarray, keep: np.ndarray, shape: tuple[int, ...]
) -> tuple[np.ndarray, np.ndarray, list[LinearConstraint]]:
    n = c.size
    battery = keep % shape[-1]
    items, inverse = np.unique(battery, return_inverse=True)
    k = items.size
    # rows 0..k-1: sum of u over the battery's combinations - z_b = 0; row k: sum z = 1
    rows = np.concatenate([inverse, np.arange(k), np.full(k, k)])
    cols = np.concatenate([np.arange(n), n + np.arange(k), n + np.arange(k)])
    vals = np.concatenate([np.ones(n), -np.ones(k), np.ones(k)])
    a = sparse.csc_array((vals, (rows, cols)), shape=(k + 1, n + k))
    lb = np.concatenate([np.zeros(k), [1.0]])
    c_all = np.concatenate([c, np.zeros(k)])
    integrality = np.concatenate([np.zeros(n), np.ones(k)])
    # scipy's LinearConstraint is unannotated: the checker takes lb and ub to be floats, the
    # type of their defaults (-inf, inf); they take arrays
    return c_all, integrality, [LinearConstraint(a, lb, lb)]  # pyright: ignore[reportArgumentType]


def _unit_model(c: np.ndarray) -> tuple[np.ndarray, np.ndarray, list[LinearConstraint]]:
    n = c.size
    one_row = sparse.csr_array((np.ones(n), (np.zeros(n, int), np.arange(n))), shape=(1, n))
    return c, np.ones(n), [LinearConstraint(one_row, 1.0, 1.0)]


def _factored_model(
    c: np.ndarray, keep: np.ndarray, shape: tuple[int, ...]
) -> tuple[np.ndarray, np.ndarray, list[LinearConstraint]]:
    n = c.size
    p_idx, m_idx, b_idx = np.unravel_index(keep, shape)
    cols_u = np.arange(n)
    blocks = []
    offset = n
    rows_total = 0
    row_parts, col_parts, val_parts = [], [], []
    lbs, ubs = [], []
    for idx in (p_idx, m_idx, b_idx):
        items, inverse = np.unique(idx, return_inverse=True)
        k = items.size
        blocks.append(k)
        # marginal rows: sum_{combos with item j} u - x_j = 0
        row_parts += [rows_total + inverse, rows_total + np.arange(k)]
        col_parts += [cols_u, offset + np.arange(k)]
        val_parts += [np.ones(n), -np.ones(k)]
        lbs.append(np.zeros(k))
        ubs.append(np.zeros(k))
        rows_total += k
        # one-hot row over the item binaries
        row_parts.append(np.full(k, rows_total))
        col_parts.append(offset + np.arange(k))
        val_parts.append(np.ones(k))
        lbs.append(np.ones(1))
        ubs.append(np.ones(1))
        rows_total += 1
        offset += k
    a = sparse.csr_array(
        (np.concatenate(val_parts), (np.concatenate(row_parts), np.concatenate(col_parts))),
        shape=(rows_total, offset),
    )
    c_all = np.concatenate([c, np.zeros(offset - n)])
    integrality = np.concatenate([np.zeros(n), np.ones(offset - n)])
    lb, ub = np.concatenate(lbs), np.concatenate(ubs)
    return c_all, integrality, [LinearConstraint(a, lb, ub)]  # pyright: ignore[reportArgumentType]
