"""The contract between the design model and the selection layer.

The model (``optimizer.model.design_model``) computes every quantity of every discrete design
exactly; the selection layer (enumeration, MILP) only chooses among them. A
``DesignGrid`` holds, for one actuator count and one payload, every metric on the
full (propeller, motor, battery) product as arrays of shape ``(P, M, B)``, and the
physical limits as ``Check``s. Selection code depends only on this module, so it
can be tested on synthetic grids and works for any model that fills one.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Literal

import numpy as np

#: Metric keys every grid carries (SI or the unit in the name), one array (P, M, B) each.
METRIC_KEYS: tuple[str, ...] = (
    "flight_time_min",
    "time_constant_ms",
    "price",
    "total_mass_kg",
    "hover_rpm",
    "propeller_power_w",
    "power_w",
    "current_a",
    "roll_inertia_kgm2",
    "pitch_inertia_kgm2",
)


@dataclass(frozen=True)
class Check:
    """One physical limit: ``value <= limit`` (sense '<=') or ``value >= limit``.

    ``value`` and ``limit`` broadcast to the grid shape (P, M, B).
    """

    label: str
    unit: str
    value: np.ndarray
    limit: np.ndarray
    sense: Literal["<=", ">="] = "<="

    def margin(self) -> np.ndarray:
        """Signed slack in the check's unit: >= 0 where satisfied."""
        diff = np.asarray(self.limit, float) - np.asarray(self.value, float)
        return diff if self.sense == "<=" else -diff


@dataclass(frozen=True)
class DesignGrid:
    """All designs for one actuator count: metrics and limit checks on (P, M, B)."""

    n_actuators: int
    payload_kg: float
    propeller_ids: tuple[str, ...]
    motor_ids: tuple[str, ...]
    battery_ids: tuple[str, ...]
    metrics: dict[str, np.ndarray]
    checks: tuple[Check, ...] = ()
    notes: dict[str, str] = field(default_factory=dict)

    @property
    def shape(self) -> tuple[int, int, int]:
        return (len(self.propeller_ids), len(self.motor_ids), len(self.battery_ids))

    def feasible(self) -> np.ndarray:
        """Boolean (P, M, B): every check satisfied (with a tiny relative tolerance)."""
        return meets_checks(self, self.checks)


def meets_checks(grid: DesignGrid, checks: Sequence[Check]) -> np.ndarray:
    """Boolean (P, M, B): every one of ``checks`` satisfied on ``grid``.

    The one feasibility test (a tiny relative tolerance on each limit): selection, the
    flyable-rule reports and the flight model's design lists all use it, so they agree
    on which designs are feasible.
    """
    ok = np.ones(grid.shape, dtype=bool)
    for check in checks:
        tol = 1e-9 * np.maximum(1.0, np.abs(np.asarray(check.limit, float)))
        ok &= np.broadcast_to(check.margin() >= -tol, grid.shape)
    return ok
