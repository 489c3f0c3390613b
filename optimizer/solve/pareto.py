"""Exact Pareto fronts of two objectives: epsilon-constraint MILP, checked by enumeration.

For costs ``cx``, ``cy`` (both minimised; "max" metrics negated as in
``optimizer.solve.objectives``) over the feasible designs of one grid, the front is the set of
non-dominated points. The epsilon-constraint method walks it from the best ``cx``:

1. ``x* = min cx`` subject to ``cy <= eps`` (eps = +inf first);
2. ``y* = min cy`` subject to ``cx <= x*`` and ``cy <= eps`` (lexicographic, so the
   point is non-dominated, not merely weakly);
3. record the point, set ``eps = y* - tol`` and repeat until step 1 is infeasible.

Each step is the exact block MILP of ``optimizer.solve.milp_exact`` (HiGHS, zero gap). The
epsilon row ``sum_c cy_c u_c <= eps`` is applied as a column filter (every column with
``cy_c > eps`` dropped): since exactly one column is chosen, the two are the same set of
integer solutions, and the filter keeps the block model's LP relaxation integral (the
row would not: within one battery block the continuous weights could mix two designs to
meet it). Points whose ``cy`` differ by less than ``RTOL`` (relative) count as one; among
designs at the same point, the lowest flat index is the representative, for the MILP and
the enumeration alike. Every solve returns one
front point, so a front of k points costs 2k + 1 MILPs.

:func:`enumerate_front` is the independent oracle: sort by ``(cx, cy)`` and keep each
point whose ``cy`` beats every earlier one. Vectorised, it is also the front of any two
columns of a sweep file's rows (``optimizer.sweep.sweep_file``, ``pareto --from``).
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from optimizer.solve import milp_exact

#: Relative tolerance below which two costs are the same point of the front.
RTOL = 1e-9


def _tol(v: np.ndarray | float) -> np.ndarray | float:
    return RTOL * np.maximum(np.abs(v), 1.0)


@dataclass(frozen=True)
class FrontResult:
    """Flat indices of the front (in increasing ``cx``) and how it was found."""

    indices: np.ndarray
    method: str
    solves: int
    time_s: float


def _representative(cx: np.ndarray, cy: np.ndarray, ok: np.ndarray, x: float, y: float) -> int:
    """Lowest flat index among feasible designs at exactly (x, y)."""
    return int(np.flatnonzero(ok & (cx <= x) & (cy <= y))[0])


def enumerate_front(cx: np.ndarray, cy: np.ndarray, ok: np.ndarray) -> FrontResult:
    """Non-dominated set of (cx, cy) over ``ok`` by sorting (the oracle).

    Sorted by (cx, cy, index), a point is on the front when its cy is at least ``RTOL``
    (relative) below every earlier point's.
    """
    start = time.perf_counter()
    cx, cy = np.asarray(cx, float).ravel(), np.asarray(cy, float).ravel()
    ok = np.asarray(ok, bool).ravel() & np.isfinite(cx) & np.isfinite(cy)
    idx = np.flatnonzero(ok)
    order = idx[np.lexsort((idx, cy[idx], cx[idx]))]
    ys = cy[order]
    # candidates: where the running minimum of cy drops (a strictly falling sequence)
    prev_min = np.concatenate([[np.inf], np.minimum.accumulate(ys)[:-1]])
    cand = np.flatnonzero(ys < prev_min)
    keep = _tolerance_walk(ys[cand])
    return FrontResult(order[cand[keep]].astype(int), "exact", 0, time.perf_counter() - start)


def _tolerance_walk(y: np.ndarray) -> np.ndarray:
    """Which of the strictly falling ``y`` stay on the front: the first, then each at least
    ``RTOL`` below the last one kept (closer ones are the same point).

    A value that far below its predecessor is that far below every earlier kept one too
    (``v - tol(v)`` rises with v), so only runs of close neighbours need the sequential
    walk: vectorised for millions of rows, a Python loop only over near-ties.
    """
    keep = np.ones(y.size, bool)
    if y.size < 2:
        return keep
    close = np.flatnonzero(y[1:] > y[:-1] - _tol(y[:-1])) + 1
    keep[close] = False
    best, prev = np.inf, -1
    for pos in close:
        if prev != pos - 1:  # its predecessor is not close to its own: kept
            best = y[pos - 1]
        if y[pos] <= best - _tol(best):
            keep[pos] = True
            best = y[pos]
        prev = pos
    return keep


def milp_front(
    cx: np.ndarray, cy: np.ndarray, ok: np.ndarray, max_points: int = 10_000
) -> FrontResult:
    """The front by the epsilon-constraint MILP (see the module doc)."""
    start = time.perf_counter()
    shape = np.shape(cx)
    cx_f, cy_f = np.asarray(cx, float).ravel(), np.asarray(cy, float).ravel()
    ok = np.asarray(ok, bool).ravel() & np.isfinite(cx_f) & np.isfinite(cy_f)
    eps = np.inf
    points: list[int] = []
    solves = 0
    while len(points) < max_points:
        allowed = ok & (cy_f <= eps)
        first = milp_exact.solve(cx_f.reshape(shape), allowed.reshape(shape))
        solves += 1
        if first.index is None:
            break
        # the solver's design is optimal to ~1e-9; its exact value's equals decide ties
        x = float(cx_f[allowed & (cx_f <= cx_f[first.index] + _tol(cx_f[first.index]))].min())
        second = milp_exact.solve(cy_f.reshape(shape), (allowed & (cx_f <= x)).reshape(shape))
        solves += 1
        y0 = cy_f[second.index]
        y = float(cy_f[allowed & (cx_f <= x) & (cy_f <= y0 + _tol(y0))].min())
        points.append(_representative(cx_f, cy_f, ok, x, y))
        eps = y - _tol(y)
    return FrontResult(np.asarray(points, int), "milp", solves, time.perf_counter() - start)


def merge_fronts(points: list[tuple[float, float]]) -> np.ndarray:
    """Positions of the non-dominated entries of a short list of (cx, cy) points.

    Used to merge per-actuator-count fronts: the front of a union lies in the union of
    the fronts, so filtering the union is exact. Equal points keep the first.
    """
    if not points:
        return np.zeros(0, int)
    arr = np.asarray(points, float)
    res = enumerate_front(arr[:, 0], arr[:, 1], np.ones(len(arr), bool))
    return res.indices


def is_nondominated(cx: np.ndarray, cy: np.ndarray) -> bool:
    """Whether no point of (cx, cy) dominates another (both minimised)."""
    cx, cy = np.asarray(cx, float), np.asarray(cy, float)
    le = (cx[:, None] <= cx[None, :]) & (cy[:, None] <= cy[None, :])
    lt = (cx[:, None] < cx[None, :]) | (cy[:, None] < cy[None, :])
    dom = le & lt
    np.fill_diagonal(dom, False)
    return not dom.any()
