"""Which designs a sweep flies: every one ``optimize`` would consider with the same options.

The grids are ``optimize``'s own (``optimizer.solve.selection_options.grid_builder``: measured
overrides, the flyable rules; with cells in series and parallel one grid per series count,
as ``optimizer.solve.packs.optimize_packs`` builds them), and a design is in the sweep when it
meets every check of its grid (the hover margin, the rules, the limits:
``optimizer.flight.design.feasible_indices``). Each becomes one row of a plan: its keys,
id, the static numbers, the flight model's parameters as numbers and the measured
spreads of its constants
(``optimizer.flight.design.setup``, so a sweep flies what ``rotorbench fly`` flies).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd

from optimizer.catalogs.catalog import Catalog
from optimizer.errors import RequestError
from optimizer.flight.design import design_std, feasible_indices, setup
from optimizer.flight.uncertainty import QUANTITIES
from optimizer.flight.vehicle import FLIGHT_ACTUATORS
from optimizer.model.design_model import ModelGrid
from optimizer.model.grid import METRIC_KEYS
from optimizer.sweep.flight_params import STD_PREFIX, param_columns, params_of
from optimizer.sweep.keys import DESIGN_KEYS, design_id
from optimizer.sweep.model_params import model_params, modelled

#: a grid builder as ``optimizer.solve.selection.optimize`` takes it: (catalog, N, payload) -> grid
GridBuilder = Callable[[Catalog, int, float], Any]


@dataclass(frozen=True)
class Packs:
    """Cells in series and in parallel (``--series``, ``--parallel``): the catalog's
    batteries read as cells (``optimizer.solve.packs``)."""

    series: tuple[int, ...]
    parallel: tuple[int, ...] = (1,)


def plan_designs(catalog: Catalog, actuators: Sequence[int], payload_kg: float = 0.0,
                 build_grid: GridBuilder | None = None, packs: Packs | None = None,
                 **setup_kwargs: Any) -> pd.DataFrame:
    """One row per design to fly, in a fixed order: actuator counts as given, series
    counts in order, then catalog order (propeller, motor, battery).

    ``setup_kwargs`` go to ``optimizer.flight.design.setup`` (layout, step, drag)."""
    for n in actuators:
        if n not in FLIGHT_ACTUATORS:
            raise RequestError(f"--actuators: the flight model flies 4, 6 or 8, got {n}")
    if build_grid is None:
        from optimizer.model.design_model import evaluate_grid as build_grid
    frames = []
    for n in dict.fromkeys(actuators):
        if packs is None:
            frames.append(grid_designs(catalog, build_grid(catalog, n, payload_kg),
                                       **setup_kwargs))
            continue
        from optimizer.solve.packs import cells_of, packs_at

        cells = cells_of(catalog)
        for s in packs.series:
            sub = packs_at(catalog, cells, s, packs.parallel)
            frames.append(grid_designs(sub, build_grid(sub, n, payload_kg), packs=True,
                                       **setup_kwargs))
    plan = pd.concat(frames, ignore_index=True)
    if plan["design_id"].duplicated().any():  # 64-bit hash collision or repeated keys
        dup = plan.loc[plan["design_id"].duplicated(), "design_id"].iloc[0]
        raise RequestError(f"two designs of the sweep share the id {dup}: the catalog "
                           "repeats a part id")
    return plan


def grid_designs(catalog: Catalog, grid: ModelGrid, *, packs: bool = False,
                 **setup_kwargs: Any) -> pd.DataFrame:
    """The plan rows of every design of ``grid`` that meets its checks. ``packs``: the
    catalog's batteries are packs (``optimizer.solve.packs.pack_frame``), keyed by their cell."""
    idx = np.array(feasible_indices(grid), dtype=int).reshape(-1, 3)
    ii, jj, kk = idx[:, 0], idx[:, 1], idx[:, 2]
    bats = catalog.batteries
    if packs:
        battery = bats["cell"].to_numpy()[kk]
        series = bats["series"].to_numpy(int)[kk]
        parallel = bats["parallel"].to_numpy(int)[kk]
    else:
        battery = np.asarray(grid.battery_ids, dtype=object)[kk]
        series = bats["cells"].to_numpy(float)[kk].astype(int)
        parallel = np.ones(len(kk), dtype=int)
    keys = {
        "actuators": np.full(len(kk), grid.n_actuators, dtype=int),
        "propeller": np.asarray(grid.propeller_ids, dtype=object)[ii],
        "motor": np.asarray(grid.motor_ids, dtype=object)[jj],
        "battery": battery,
        "series": series,
        "parallel": parallel,
    }
    ids = [design_id(*k) for k in zip(*(keys[c] for c in DESIGN_KEYS), strict=True)]
    frame = pd.DataFrame({"design_id": ids, **keys})
    for key in METRIC_KEYS:
        frame[key] = grid.metrics[key][ii, jj, kk]
    frame["thrust_to_weight"] = thrust_to_weight(catalog, grid)[ii, jj, kk]
    step = setup_kwargs.get("step")
    flight = model_params(catalog, grid, idx, setup_kwargs.get("layout", "x"),
                          setup_kwargs.get("drag_n_s_m", 0.0))
    alone = ~(modelled(grid, idx, step) & flight.pop("valid").to_numpy(bool))
    errors = [""] * len(idx)
    spread = pd.DataFrame(0.0, index=flight.index, columns=list(QUANTITIES))
    for row in np.flatnonzero(alone):  # measured numbers, a step run or a refusal: setup's
        i, j, k = (int(v) for v in idx[row])
        index = (i, j, k)
        # the measured spreads of the constants flown (``--samples`` draws from them)
        spread.iloc[row] = pd.Series(design_std(grid, index, step))[list(QUANTITIES)]
        try:
            params = params_of(*setup(catalog, grid, index, **setup_kwargs))
        except Exception as exc:  # a design the flight model refuses is a row with why
            params = dict.fromkeys(param_columns(), math.nan)
            errors[row] = f"{type(exc).__name__}: {exc}"
        flight.iloc[row] = pd.Series(params)[list(param_columns())]
    frame = pd.concat([frame, flight, spread.add_prefix(STD_PREFIX)], axis=1)
    frame["setup_error"] = errors  # "" when the flight model took the design
    return frame


def thrust_to_weight(catalog: Catalog, grid: ModelGrid) -> np.ndarray:
    """Full-throttle thrust of all actuators over the weight, (P, M, B): the grid's own
    where its hover-margin check computed it, else the same formula (E.1, E.4-E.7 with
    I_0; ``optimizer.model.design_model.evaluate_grid``) on the grid's voltage and hover thrust."""
    extras = grid.extras
    if "thrust_to_weight" in extras:
        return np.asarray(extras["thrust_to_weight"])
    from optimizer.model.operating_points import at_throttle
    from optimizer.model.sheet import drive_of

    top = at_throttle(drive_of(catalog), 1.0, extras["voltage_v"])
    return np.broadcast_to(top.thrust_n / extras["hover_thrust_n"], grid.shape)
