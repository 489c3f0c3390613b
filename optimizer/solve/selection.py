"""Design selection: one entry point from a request to one design per actuator count.

For each actuator count the model builds a ``DesignGrid`` (payload is an input
of the grid); the grid's physical limits plus the request's requirements
(minimum flight time, maximum time constant) give the feasible set; the chosen
method (``milp``: ``optimizer.solve.milp_exact``, ``exact``: ``optimizer.solve.exhaustive``)
finds the optimal cost; the tie-break below picks one design among those that
reach it; infeasible actuator counts get an explanation from the closest design.

Ties (one rule for every method, implemented once in ``break_ties``):
  1. the tied set is every feasible design whose cost is within
     ``TIE_RTOL * max(|v*|, mean |cost|)`` (+ ``TIE_ATOL``) of the optimum ``v*``;
     a method's answer is first refined to the smallest cost in that set, so a
     solver tolerance can never move the set;
  2. among the tied designs, compare lexicographically by ``TIE_ORDER`` (each
     metric in its own sense, equal within the same relative tolerance),
     skipping the objective's own metric: longer flight time, then lower price,
     faster actuators (time constant), lower power, lower mass, lower roll and
     pitch inertia;
  3. then by catalog position (propeller, motor, battery row order).
A lexicographic minimum is never dominated in these metrics by another tied
design, and designs outside the tied set are worse in the objective.

The best actuator count: lowest cost (for weighted objectives the normalisation
ranges are shared across actuator counts), ties broken by the same order, then
fewer actuators.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np

from optimizer.catalogs.catalog import Catalog
from optimizer.errors import RequestError
from optimizer.model.grid import METRIC_KEYS, Check, DesignGrid, meets_checks
from optimizer.solve import exhaustive, milp_exact
from optimizer.solve.exhaustive import SolveOutcome
from optimizer.solve.objectives import Objective, metric_ranges

Method = Literal["milp", "exact", "thesis"]
METHODS: tuple[str, ...] = ("milp", "exact", "thesis")

TIE_RTOL = 1e-6
TIE_ATOL = 1e-12

#: Secondary order for ties: (metric, sense), compared lexicographically.
TIE_ORDER: tuple[tuple[str, str], ...] = (
    ("flight_time_min", "max"),
    ("price", "min"),
    ("time_constant_ms", "min"),
    ("power_w", "min"),
    ("total_mass_kg", "min"),
    ("roll_inertia_kgm2", "min"),
    ("pitch_inertia_kgm2", "min"),
)

#: JSON keys of every design entry (docs/optimizer.md), in order.
ENTRY_KEYS: tuple[str, ...] = (
    "actuators",
    "feasible",
    "propeller",
    "motor",
    "battery",
    "flight_time_min",
    "time_constant_ms",
    "price",
    "total_mass_kg",
    "hover_rpm",
    "propeller_power_w",
    "current_a",
    "roll_inertia_kgm2",
    "pitch_inertia_kgm2",
    "solve_time_s",
)


@dataclass(frozen=True)
class Requirements:
    """What the user asks for beyond the physical limits of the grid."""

    payload_kg: float = 0.0
    min_flight_time_min: float | None = None
    max_time_constant_ms: float | None = None

    def validate(self) -> Requirements:
        for name, value in (
            ("payload", self.payload_kg),
            ("minimum flight time", self.min_flight_time_min),
            ("maximum time constant", self.max_time_constant_ms),
        ):
            if value is not None and (not math.isfinite(value) or value < 0):
                raise RequestError(f"{name}: expected a finite number >= 0, got {value}")
        return self

    def checks(self, grid: DesignGrid) -> tuple[Check, ...]:
        """The requirement checks on a grid (payload is already inside the grid)."""
        out = []
        if self.min_flight_time_min is not None:
            out.append(
                Check(
                    "flight time (required minimum)",
                    "min",
                    grid.metrics["flight_time_min"],
                    np.asarray(self.min_flight_time_min, float),
                    ">=",
                )
            )
        if self.max_time_constant_ms is not None:
            out.append(
                Check(
                    "time constant (required maximum)",
                    "ms",
                    grid.metrics["time_constant_ms"],
                    np.asarray(self.max_time_constant_ms, float),
                    "<=",
                )
            )
        return tuple(out)


@dataclass(frozen=True)
class Violation:
    """One unmet check of a design, in the check's unit."""

    label: str
    unit: str
    value: float
    limit: float
    sense: str
    shortfall: float

    @property
    def relative(self) -> float:
        return self.shortfall / abs(self.limit) if self.limit else math.inf

    def describe(self) -> str:
        unit = f" {self.unit}" if self.unit else ""
        op = ">" if self.sense == "<=" else "<"
        word = "over" if self.sense == "<=" else "short"
        if not math.isfinite(self.value):
            return f"{self.label} is not finite (limit {self.limit:.4g}{unit})"
        pct = f", {100 * self.relative:.1f} %" if math.isfinite(self.relative) else ""
        return (
            f"{self.label} {self.value:.4g}{unit} {op} limit {self.limit:.4g}{unit} "
            f"({word} by {self.shortfall:.3g}{unit}{pct})"
        )


@dataclass
class DesignResult:
    """The selected design of one actuator count (or why there is none)."""

    actuators: int
    feasible: bool
    index: tuple[int, int, int] | None
    propeller: str | None
    motor: str | None
    battery: str | None
    metrics: dict[str, float]
    cost: float
    solve_time_s: float
    grid_time_s: float
    method: str
    status: str
    n_candidates: int
    n_designs: int
    n_tied: int = 0
    mip_gap: float | None = None
    reason: str | None = None
    closest: dict[str, Any] | None = None
    extra: dict[str, Any] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        """The JSON entry: the issue's keys first, then details."""
        out: dict[str, Any] = {
            "actuators": self.actuators,
            "feasible": self.feasible,
            "propeller": self.propeller,
            "motor": self.motor,
            "battery": self.battery,
        }
        for key in ENTRY_KEYS[5:-1]:
            out[key] = self.metrics.get(key) if self.feasible else None
        out["solve_time_s"] = self.solve_time_s
        if self.reason is not None:
            out["reason"] = self.reason
        if self.closest is not None:
            out["closest"] = self.closest
        out.update(
            {
                "power_w": self.metrics.get("power_w") if self.feasible else None,
                "objective_cost": _finite_or_none(self.cost),
                "method": self.method,
                "status": self.status,
                "mip_gap": self.mip_gap,
                "candidates": self.n_candidates,
                "designs": self.n_designs,
                "tied": self.n_tied,
                "grid_time_s": self.grid_time_s,
            }
        )
        out.update(self.extra)
        return out


@dataclass
class SelectionResult:
    """All actuator counts of one request and the best of them."""

    objective: Objective
    method: str
    requirements: Requirements
    designs: list[DesignResult]
    best: DesignResult | None
    source: str = ""

    @property
    def any_feasible(self) -> bool:
        return self.best is not None

    def to_dict(self) -> dict[str, Any]:
        return {
            "objective": self.objective.name,
            "method": self.method,
            "catalog": self.source,
            "payload_kg": self.requirements.payload_kg,
            "min_flight_time_min": self.requirements.min_flight_time_min,
            "max_time_constant_ms": self.requirements.max_time_constant_ms,
            "designs": [d.to_dict() for d in self.designs],
            "best": None if self.best is None else self.best.to_dict(),
        }


# --------------------------------------------------------------------------- ties


def _tol(value: float, scale: float) -> float:
    return TIE_RTOL * max(abs(value), scale) + TIE_ATOL


def tied_set(cost: np.ndarray, ok: np.ndarray, value: float) -> np.ndarray:
    """Flat indices of feasible designs within the tie tolerance of the optimum.

    ``value`` is a method's optimum; it is first refined to the smallest cost
    within tolerance of it, so every method that lands inside the tolerance
    yields the same set.
    """
    flat = np.asarray(cost, float).ravel()
    mask = np.asarray(ok, bool).ravel() & np.isfinite(flat)
    scale = float(np.mean(np.abs(flat[mask]))) if mask.any() else 0.0
    near = np.flatnonzero(mask & (flat <= value + _tol(value, scale)))
    if near.size == 0:
        return near
    best = float(flat[near].min())
    return np.flatnonzero(mask & (flat <= best + _tol(best, scale)))


def lexicographic_pick(candidates: np.ndarray, columns: Sequence[tuple[np.ndarray, str]]) -> int:
    """Index into ``candidates`` order: lexicographic best by ``columns`` then position.

    ``columns`` are (values over the candidates, sense); NaN counts as worst;
    values within the tie tolerance of the best are equal.
    """
    alive = np.arange(len(candidates))
    for values, sense in columns:
        if alive.size <= 1:
            break
        v = np.asarray(values, float)[alive]
        v = -v if sense == "max" else v
        v = np.where(np.isfinite(v), v, np.inf)
        best = float(v.min())
        if not math.isfinite(best):
            continue
        alive = alive[v <= best + _tol(best, 0.0)]
    # remaining ties: smallest candidate (catalog position / fewer actuators)
    return int(alive[np.argmin(np.asarray(candidates)[alive])])


def break_ties(grid: DesignGrid, candidates: np.ndarray, objective: Objective) -> int:
    """The flat index chosen among tied ``candidates`` of one grid (see module doc)."""
    candidates = np.asarray(candidates)
    if candidates.size == 1:
        return int(candidates[0])
    own = set(objective.metrics) if objective.is_single else set()
    columns = []
    for metric, sense in TIE_ORDER:
        if metric in own or metric not in grid.metrics:
            continue
        values = np.broadcast_to(np.asarray(grid.metrics[metric], float), grid.shape).ravel()
        columns.append((values[candidates], sense))
    return int(candidates[lexicographic_pick(candidates, columns)])


# ----------------------------------------------------------------- infeasibility


def _violations(checks: Sequence[Check], shape: tuple[int, ...]) -> np.ndarray:
    """Total normalised violation per design: sum of shortfall / |limit| (inf if NaN)."""
    total = np.zeros(shape)
    for check in checks:
        margin = np.broadcast_to(check.margin(), shape)
        limit = np.abs(np.broadcast_to(np.asarray(check.limit, float), shape))
        scale = np.where(limit > 0, limit, 1.0)
        part = np.maximum(0.0, -margin) / scale
        total = total + np.where(np.isfinite(part), part, np.inf)
    return total


def _design_violations(
    checks: Sequence[Check], shape: tuple[int, ...], flat_index: int
) -> list[Violation]:
    out = []
    idx = np.unravel_index(flat_index, shape)
    for check in checks:
        value = float(np.broadcast_to(np.asarray(check.value, float), shape)[idx])
        limit = float(np.broadcast_to(np.asarray(check.limit, float), shape)[idx])
        margin = float(np.broadcast_to(check.margin(), shape)[idx])
        tol = 1e-9 * max(1.0, abs(limit))
        if not math.isfinite(margin) or margin < -tol:
            out.append(Violation(check.label, check.unit, value, limit, check.sense, abs(margin)))
    return out


def explain_infeasible(
    grid: DesignGrid, checks: Sequence[Check], cost: np.ndarray
) -> tuple[str, dict[str, Any]]:
    """Why no design of the grid is feasible: the closest design and what it misses.

    Closest = minimum total normalised violation (sum over checks of shortfall
    divided by |limit|), ties by catalog position. Checks that no design at all
    can meet are named first, with the best value any design reaches.
    """
    shape = grid.shape
    impossible = []
    for check in checks:
        margin = np.broadcast_to(check.margin(), shape)
        finite = np.isfinite(margin)
        if not np.any(finite & (margin >= -1e-9 * max(1.0, float(np.max(np.abs(check.limit)))))):
            best = int(np.argmax(np.where(finite, margin, -np.inf)))
            v = _design_violations([check], shape, best)
            if v:
                impossible.append(v[0])
    total = _violations(checks, shape)
    if not np.isfinite(total).any():
        total = np.where(np.isfinite(np.asarray(cost, float)), 0.0, np.inf)
    closest = int(np.argmin(total))
    i, j, k = (int(x) for x in np.unravel_index(closest, shape))
    misses = _design_violations(checks, shape, closest)
    ids = f"{grid.propeller_ids[i]}+{grid.motor_ids[j]}+{grid.battery_ids[k]}"
    parts = []
    for v in impossible:
        unit = f" {v.unit}" if v.unit else ""
        parts.append(
            f"no design meets {v.label} (limit {v.limit:.4g}{unit}; best {v.value:.4g}{unit})"
        )
    if misses:
        parts.append(f"closest design {ids}: " + "; ".join(v.describe() for v in misses))
    else:
        parts.append(f"closest design {ids}: objective not finite")
    reason = "; ".join(parts)
    detail = {
        "propeller": grid.propeller_ids[i],
        "motor": grid.motor_ids[j],
        "battery": grid.battery_ids[k],
        "total_normalised_violation": _finite_or_none(float(total.ravel()[closest])),
        "violations": [
            {
                "check": v.label,
                "unit": v.unit,
                "value": _finite_or_none(v.value),
                "limit": v.limit,
                "sense": v.sense,
                "shortfall": _finite_or_none(v.shortfall),
                "relative": _finite_or_none(v.relative),
            }
            for v in misses
        ],
        "impossible": [v.label for v in impossible],
    }
    return reason, detail


# ---------------------------------------------------------------------- selection


def _finite_or_none(x: float | None) -> float | None:
    return None if x is None or not math.isfinite(x) else float(x)


def _solve(method: str, cost: np.ndarray, ok: np.ndarray, **options: Any) -> SolveOutcome:
    if method == "exact":
        return exhaustive.solve(cost, ok)
    if method == "milp":
        return milp_exact.solve(cost, ok, **options)
    raise RequestError(f"unknown method {method!r}; expected one of {', '.join(METHODS)}")


def select_from_grids(
    grids: Sequence[DesignGrid],
    objective: Objective,
    requirements: Requirements | None = None,
    method: str = "milp",
    *,
    grid_times: Sequence[float] | None = None,
    milp_options: dict[str, Any] | None = None,
    source: str = "",
) -> SelectionResult:
    """Select one design per grid (one grid per actuator count) and the best overall."""
    req = (requirements or Requirements()).validate()
    if method == "thesis":
        raise RequestError("method 'thesis' needs a catalog; use optimize()")
    if method not in METHODS:
        raise RequestError(f"unknown method {method!r}; expected one of {', '.join(METHODS)}")
    checks_per_grid = [(*g.checks, *req.checks(g)) for g in grids]
    feasible = [meets_checks(g, checks) for g, checks in zip(grids, checks_per_grid, strict=True)]
    ranges = metric_ranges(grids, feasible, objective.metrics) if objective.needs_ranges() else None
    designs = []
    for n, (grid, checks, ok) in enumerate(zip(grids, checks_per_grid, feasible, strict=True)):
        cost = objective.cost(grid, ranges)
        ok = ok & np.isfinite(cost)
        outcome = _solve(method, cost, ok, **(milp_options or {}))
        gtime = grid_times[n] if grid_times is not None else 0.0
        designs.append(_result(grid, checks, cost, ok, outcome, objective, method, gtime))
    return SelectionResult(objective, method, req, designs, pick_best(designs), source)


def _design_at(grid: DesignGrid, index: tuple[int, int, int]) -> dict[str, Any]:
    """The ``DesignResult`` fields that name design ``index`` of ``grid`` and its metrics."""
    i, j, k = index
    metrics = {
        key: float(np.broadcast_to(np.asarray(grid.metrics[key], float), grid.shape)[i, j, k])
        for key in METRIC_KEYS
        if key in grid.metrics
    }
    return dict(index=(i, j, k), propeller=grid.propeller_ids[i], motor=grid.motor_ids[j],
                battery=grid.battery_ids[k], metrics=metrics)


def _no_design(grid: DesignGrid, checks: Sequence[Check], cost: np.ndarray,
               reason_prefix: str = "") -> dict[str, Any]:
    """The ``DesignResult`` fields of an actuator count without a feasible design."""
    reason, detail = explain_infeasible(grid, checks, cost)
    return dict(feasible=False, index=None, propeller=None, motor=None, battery=None,
                metrics={}, cost=math.nan, reason=reason_prefix + reason, closest=detail)


def _result(
    grid: DesignGrid,
    checks: Sequence[Check],
    cost: np.ndarray,
    ok: np.ndarray,
    outcome: SolveOutcome,
    objective: Objective,
    method: str,
    grid_time: float,
) -> DesignResult:
    common: dict[str, Any] = dict(
        actuators=grid.n_actuators,
        solve_time_s=outcome.solve_time_s,
        grid_time_s=grid_time,
        method=method,
        n_candidates=outcome.n_candidates,
        n_designs=int(np.prod(grid.shape)),
        mip_gap=outcome.mip_gap,
    )
    if outcome.index is None:
        return DesignResult(**_no_design(grid, checks, cost), status=outcome.status, **common)
    tied = tied_set(cost, ok, outcome.value)
    if outcome.status != "optimal":
        # time limit with an incumbent: report it as found, not as proven optimal
        tied = np.array([outcome.index])
    elif tied.size == 0 or outcome.index not in set(tied.tolist()):
        raise RuntimeError(
            f"{method} returned a design {outcome.index} outside the optimal set "
            f"(value {outcome.value}); solver status {outcome.status}"
        )
    chosen = break_ties(grid, tied, objective)
    i, j, k = (int(x) for x in np.unravel_index(chosen, grid.shape))
    return DesignResult(
        feasible=True,
        **_design_at(grid, (i, j, k)),
        cost=float(np.asarray(cost).ravel()[chosen]),
        status=outcome.status,
        n_tied=int(tied.size),
        extra={"tied_designs": tied_names(grid, tied, chosen)} if tied.size > 1 else {},
        **common,
    )


#: At most this many tied designs are named (the count is always given).
TIED_NAMED = 12


def tied_names(grid: DesignGrid, tied: np.ndarray, chosen: int) -> list[str]:
    """``propeller/motor/battery`` ids of the tied designs, the chosen one first."""
    order = [chosen, *(int(t) for t in tied if int(t) != chosen)][:TIED_NAMED]
    names = []
    for flat in order:
        i, j, k = (int(x) for x in np.unravel_index(flat, grid.shape))
        names.append(f"{grid.propeller_ids[i]}/{grid.motor_ids[j]}/{grid.battery_ids[k]}")
    return names


def pick_best(designs: Sequence[DesignResult]) -> DesignResult | None:
    """Lowest cost across actuator counts; ties by ``TIE_ORDER``, then fewer actuators."""
    ok = [d for d in designs if d.feasible]
    if not ok:
        return None
    costs = np.array([d.cost for d in ok])
    best = float(costs.min())
    scale = float(np.mean(np.abs(costs)))
    tied = [d for d, c in zip(ok, costs, strict=True) if c <= best + _tol(best, scale)]
    order = np.array([d.actuators for d in tied])
    columns = [
        (np.array([d.metrics.get(m, math.nan) for d in tied]), sense) for m, sense in TIE_ORDER
    ]
    return tied[lexicographic_pick(order, columns)]


def optimize(
    catalog: Catalog,
    objective: Objective,
    actuators: Sequence[int] = (4, 6, 8),
    requirements: Requirements | None = None,
    method: str = "milp",
    *,
    build_grid: Callable[[Catalog, int, float], DesignGrid] | None = None,
    milp_options: dict[str, Any] | None = None,
    thesis_options: dict[str, Any] | None = None,
) -> SelectionResult:
    """Build a grid per actuator count from ``catalog`` and select (the CLI's entry point).

    ``method="thesis"`` solves Paper E's own linearised MILP (``optimizer.
    thesis_formulation``) and reports the exact model's values of its choice.
    """
    req = (requirements or Requirements()).validate()
    if method not in METHODS:
        raise RequestError(f"unknown method {method!r}; expected one of {', '.join(METHODS)}")
    if not actuators:
        raise RequestError("actuators: give at least one actuator count, e.g. 4 6 8")
    if build_grid is None:
        from optimizer.model.design_model import evaluate_grid as build_grid
    grids, times = [], []
    for n in dict.fromkeys(actuators):
        start = time.perf_counter()
        grids.append(build_grid(catalog, n, req.payload_kg))
        times.append(time.perf_counter() - start)
    source = str(getattr(catalog, "source", ""))
    if method == "thesis":
        return _select_thesis(catalog, grids, times, objective, req, thesis_options or {}, source)
    return select_from_grids(
        grids,
        objective,
        req,
        method,
        grid_times=times,
        milp_options=milp_options,
        source=source,
    )


def _select_thesis(
    catalog: Catalog,
    grids: Sequence[DesignGrid],
    times: Sequence[float],
    objective: Objective,
    req: Requirements,
    options: dict[str, Any],
    source: str,
) -> SelectionResult:
    """Paper E's formulation per actuator count; designs evaluated by the exact model."""
    from optimizer.solve.thesis_formulation import solve_thesis

    if catalog.constants.current_model != "thesis":
        raise RequestError(
            "method thesis is Paper E's linearised MILP with its own current (E.67); "
            "with current model 'drive' use method milp or exact"
        )

    if objective.is_single:
        spec: Any = objective.terms[0][0].name
    elif objective.normalization == "none":
        spec = {m.name: w for m, w in objective.terms}
    else:
        raise RequestError(
            "method thesis supports single objectives and weighted sums with "
            "--normalize none (Paper D adds SI values)"
        )
    designs = []
    for grid, gtime in zip(grids, times, strict=True):
        checks = (*grid.checks, *req.checks(grid))
        ok = meets_checks(grid, checks)
        cost = objective.cost(grid, None)
        start = time.perf_counter()
        res = solve_thesis(
            catalog,
            grid.n_actuators,
            spec,
            req.payload_kg,
            req.min_flight_time_min,
            req.max_time_constant_ms,
            **options,
        )
        wall = time.perf_counter() - start
        common: dict[str, Any] = dict(
            actuators=grid.n_actuators,
            solve_time_s=res.solve_time_s,
            grid_time_s=gtime,
            method="thesis",
            status=res.status,
            n_candidates=int(ok.sum()),
            n_designs=int(np.prod(grid.shape)),
            mip_gap=res.mip_gap,
        )
        if res.index is None:
            designs.append(
                DesignResult(
                    **_no_design(grid, checks, cost, "thesis formulation: "),
                    **common,
                    extra={"thesis_wall_time_s": wall},
                )
            )
            continue
        i, j, k = res.index
        designs.append(
            DesignResult(
                feasible=bool(ok[i, j, k]),
                **_design_at(grid, (i, j, k)),
                cost=float(cost[i, j, k]),
                **common,
                reason=None if ok[i, j, k] else "thesis choice violates an exact check",
                extra={
                    "linearised": dict(res.linearised),
                    "shortfall_vs_exact": res.shortfall,
                    "thesis_wall_time_s": wall,
                    "model_size": {"variables": res.n_vars, "constraints": res.n_constraints},
                },
            )
        )
    return SelectionResult(objective, "thesis", req, designs, pick_best(designs), source)
