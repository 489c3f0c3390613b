"""Does the MILP's time constant rank designs the way closed-loop flight does?

Every feasible design of one actuator count is flown through ``roll_step`` with its own
gains (the gain rule); the rows pair the design's time constant (E.35, or measured) with
its closed-loop 10-90 % roll rise time, and Spearman's rho (scipy.stats.spearmanr)
measures how well the first orders the second (the whole catalog is flown by the sweep
engine: ``optimizer.sweep.ranking.rank``). Also the filter behind
``optimize --max-roll-rise-ms``: fly candidates in objective order until one meets it.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.stats import spearmanr

from optimizer.catalogs.catalog import Catalog
from optimizer.flight.actuators import ActuatorModel
from optimizer.flight.design import gains_for, setup
from optimizer.flight.maneuvers import MANEUVERS, fly
from optimizer.flight.vehicle import Vehicle
from optimizer.model.design_model import ModelGrid
from optimizer.model.grid import DesignGrid


@dataclass(frozen=True)
class FlownDesign:
    """One design's time constant and its closed-loop roll step figures."""

    propeller: str
    motor: str
    battery: str
    time_constant_ms: float
    rise_time_ms: float | None
    overshoot_pct: float
    settling_time_ms: float | None
    saturation_pct: float
    tau_up_ms: float
    tau_down_ms: float
    final_error_pct: float
    note: str = ""  # non-empty: left out of the ranking (e.g. cannot hover)


@dataclass
class Ranking:
    """The sweep's rows and how well time constant ranks rise time."""

    actuators: int
    rows: list[FlownDesign]
    rho: float
    p_value: float
    seconds: float
    extra: dict[str, Any] = field(default_factory=dict)

    @property
    def n_ranked(self) -> int:
        return sum(1 for r in self.rows if not r.note)

    def to_dict(self) -> dict[str, Any]:
        return {
            "actuators": self.actuators,
            "designs": len(self.rows),
            "ranked": self.n_ranked,
            "spearman_rho": None if math.isnan(self.rho) else self.rho,
            "p_value": None if math.isnan(self.p_value) else self.p_value,
            "seconds": self.seconds,
            "rows": [r.__dict__ for r in self.rows],
            **self.extra,
        }


def roll_step(catalog: Catalog, grid: ModelGrid, index: tuple[int, int, int], **kwargs: Any
              ) -> FlownDesign:
    """Fly ``roll_step`` for one design of a grid (``kwargs`` go to ``design.setup``)."""
    vehicle, actuator = setup(catalog, grid, index, **kwargs)
    f = fly(vehicle, actuator, MANEUVERS["roll_step"], gains=gains_for(actuator), record=False)
    return _row(grid, index, vehicle, actuator, f.figures)


def _row(grid: DesignGrid, index: tuple[int, int, int], vehicle: Vehicle, actuator: ActuatorModel,
         fig: dict[str, Any]) -> FlownDesign:
    i, j, k = index
    return FlownDesign(
        grid.propeller_ids[i], grid.motor_ids[j], grid.battery_ids[k],
        float(grid.metrics["time_constant_ms"][i, j, k]), fig["rise_time_ms"],
        fig["overshoot_pct"], fig["settling_time_ms"], fig["saturation_pct"],
        actuator.tau_up_s * 1e3, actuator.tau_down_s * 1e3, fig["final_error_pct"],
        vehicle.hover_shortfall())


def spearman(rows: Sequence[FlownDesign]) -> tuple[float, float]:
    """Spearman's rho (and p) of time constant vs rise time over the rows without a note
    (designs that hover); NaN for fewer than 3 such rows."""
    rows = [r for r in rows if not r.note]
    if len(rows) < 3:
        return math.nan, math.nan
    tau = np.array([r.time_constant_ms for r in rows])
    rise = np.array([math.inf if r.rise_time_ms is None else r.rise_time_ms for r in rows])
    res = spearmanr(tau, rise)
    # scipy's result class is made at run time; its stubs do not name its fields
    return (float(res.statistic),  # pyright: ignore[reportAttributeAccessIssue]
            float(res.pvalue))  # pyright: ignore[reportAttributeAccessIssue]


def first_meeting(candidates: Sequence[tuple[int, int, int]], catalog: Catalog, grid: ModelGrid,
                  max_rise_ms: float, **kwargs: Any
                  ) -> tuple[tuple[int, int, int] | None, list[FlownDesign]]:
    """Fly ``candidates`` (best objective first) until one rises in roll within
    ``max_rise_ms``: that one is the best design meeting it, since every better one was
    flown and missed. Returns it (or None) and every design flown."""
    flown = []
    for idx in candidates:
        row = roll_step(catalog, grid, idx, **kwargs)
        flown.append(row)
        if not row.note and row.rise_time_ms is not None and row.rise_time_ms <= max_rise_ms:
            return idx, flown
    return None, flown
