"""``optimize --max-roll-rise-ms T``: the best design whose closed-loop roll step rises
within T.

The MILP (or enumeration) picks first. Per actuator count its design is flown through
``roll_step``; if it misses T, the other feasible designs are flown in objective order
(cost, ties in catalog order) until one meets T. That one is the best design meeting
T, proven by flight: every design with a better objective was flown and missed. The
best actuator count is then chosen again among the survivors (``pick_best``).

With a sweep file (``--from-sweep``, ``optimizer.sweep.sweep_screen.RollScreen``) nothing is
flown: the same order is read off the file's roll rise times, so the pick is the one the
flights would make (the MILP's pick if it meets T, else the lowest cost, ties in catalog
order). A design of the grid the file lacks counts as not screened: never picked, counted
in ``flight`` (``not_in_file``, and ``not_in_file_better``: how many of those have a better
objective than the pick, so could have beaten it).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from typing import Any, Protocol

import numpy as np

from optimizer.catalogs.catalog import Catalog
from optimizer.errors import RequestError
from optimizer.flight.ranking import first_meeting
from optimizer.flight.vehicle import FLIGHT_ACTUATORS
from optimizer.model.design_model import ModelGrid
from optimizer.model.grid import DesignGrid, meets_checks
from optimizer.solve.objectives import Objective, metric_ranges
from optimizer.solve.selection import (
    Requirements,
    SelectionResult,
    _design_at,
    pick_best,
)


class RollScreen(Protocol):
    """Roll rise times read from a sweep file (``optimizer.sweep.sweep_screen.RollScreen``,
    which sits above this floor: a sweep flies with ``optimizer.flight``)."""

    source: str

    def on_grid(self, grid: DesignGrid) -> Any: ...


def meet_roll_rise(result: SelectionResult, catalog: Catalog, objective: Objective,
                   requirements: Requirements, max_rise_ms: float,
                   build_grid: Callable[[Catalog, int, float], Any] | None = None,
                   screen: RollScreen | None = None, **setup_kwargs: Any) -> SelectionResult:
    """``result`` with every actuator count's design replaced by the best one that
    meets the roll rise time (or made infeasible with the reason); flown, or read from
    ``screen``."""
    if not (math.isfinite(max_rise_ms) and max_rise_ms > 0):
        raise RequestError(f"--max-roll-rise-ms: expected a time > 0 ms, got {max_rise_ms}")
    for d in result.designs:
        if d.actuators not in FLIGHT_ACTUATORS:
            raise RequestError(f"--max-roll-rise-ms: the flight model flies N = 4, 6 or 8, "
                               f"not {d.actuators}")
    if build_grid is None:
        from optimizer.model.design_model import evaluate_grid as build_grid
    grids = {d.actuators: build_grid(catalog, d.actuators, requirements.payload_kg)
             for d in result.designs}
    oks = {n: meets_checks(g, (*g.checks, *requirements.checks(g))) for n, g in grids.items()}
    ranges = (metric_ranges(grids.values(), oks.values(), objective.metrics)
              if objective.needs_ranges() else None)
    designs = []
    for d in result.designs:
        if not d.feasible or d.index is None:
            designs.append(d)
            continue
        grid = grids[d.actuators]
        cost = objective.cost(grid, ranges)
        ok = oks[d.actuators] & np.isfinite(cost)
        if screen is None:
            found, info, missed = _fly(d.index, grid, cost, ok, catalog, max_rise_ms,
                                       setup_kwargs)
        else:
            found, info, missed = _read(d.index, grid, cost, ok, screen, max_rise_ms)
        info = {"max_roll_rise_ms": max_rise_ms, **info}
        if found is None:
            designs.append(dataclasses.replace(
                d, feasible=False, index=None, propeller=None, motor=None, battery=None,
                metrics={}, cost=math.nan, n_tied=0, extra={**d.extra, "flight": info},
                reason=f"no feasible design rises in roll within {max_rise_ms:g} ms {missed}"))
            continue
        i, j, k = found
        designs.append(dataclasses.replace(
            d, **_design_at(grid, (i, j, k)), cost=float(cost[i, j, k]),
            n_tied=d.n_tied if found == d.index else 1,
            extra={**d.extra, "flight": info}))
    return dataclasses.replace(result, designs=designs, best=pick_best(designs))


Index = tuple[int, int, int]


def _fly(pick: Index, grid: ModelGrid, cost: np.ndarray, ok: np.ndarray, catalog: Catalog,
         max_rise_ms: float, setup_kwargs: dict[str, Any]
         ) -> tuple[Index | None, dict[str, Any], str]:
    """Fly the pick, then the others in objective order (ties in catalog order), until one
    meets T: (it or None, the ``flight`` info, why none did)."""
    flat = np.flatnonzero(ok.ravel())
    order = flat[np.argsort(cost.ravel()[flat], kind="stable")]
    candidates = [pick] + [_index(np.unravel_index(f, grid.shape)) for f in order]
    candidates = list(dict.fromkeys(candidates))  # the MILP's pick first, once
    found, flown = first_meeting(candidates, catalog, grid, max_rise_ms, **setup_kwargs)
    info = {"flown": len(flown),
            "roll_rise_ms": flown[-1].rise_time_ms if found is not None else None}
    fastest = min((r.rise_time_ms for r in flown if r.rise_time_ms is not None
                   and not r.note), default=None)
    best_txt = "none rose" if fastest is None else f"fastest {fastest:.0f} ms"
    return found, info, f"(flew all {len(flown)}; {best_txt})"


def _index(where: tuple[Any, ...]) -> Index:
    """A design's (propeller, motor, battery) index from numpy's per-axis indices."""
    i, j, k = (int(a) for a in where)
    return i, j, k


def _read(pick: Index, grid: DesignGrid, cost: np.ndarray, ok: np.ndarray, screen: RollScreen,
          max_rise_ms: float) -> tuple[Index | None, dict[str, Any], str]:
    """The choice :func:`_fly` would make, read off the sweep file: the pick if it meets T,
    else the lowest cost among the designs that do (``argmin``: ties in catalog order)."""
    screened = screen.on_grid(grid)
    meets = ok & (screened.rise_ms <= max_rise_ms)  # NaN (not flown, no hover...) never
    found: Index | None = None
    if meets[pick]:
        found = pick
    elif meets.any():
        flat = np.flatnonzero(meets.ravel())
        best = flat[np.argmin(cost.ravel()[flat])]
        found = _index(np.unravel_index(best, grid.shape))
    absent = ok & ~screened.present
    better = absent & (cost < cost[found]) if found is not None else absent
    info = {"source": screen.source, "flown": 0,
            "screened": int((ok & screened.present).sum()),
            "not_in_file": int(absent.sum()), "not_in_file_better": int(better.sum()),
            "roll_rise_ms": None if found is None else float(screened.rise_ms[found])}
    rose = screened.rise_ms[ok & np.isfinite(screened.rise_ms)]
    best_txt = "none rose" if rose.size == 0 else f"fastest {rose.min():.0f} ms"
    return found, info, (f"in {screen.source} ({info['screened']} screened, {best_txt}; "
                         f"{info['not_in_file']} not in the file)")
