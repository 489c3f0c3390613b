"""Objectives: which grid metric to optimise, in which sense, and weighted sums.

Every objective is turned into a *cost* array of shape (P, M, B) that is
minimised, so enumeration and the MILP share one definition:

* single objectives (Table E.2): ``cost = value`` for "min", ``cost = -value``
  for "max";
* weighted sums (Paper D, case 1: time constant + roll + pitch inertia, all
  gains one): ``cost = sum_i w_i * c_i`` where ``c_i`` is metric ``i`` in the
  sense "lower is better" and normalised by default to its range over the
  feasible designs of *all* requested actuator counts, so every term lies in
  [0, 1] and the weights are comparable across metrics and actuator counts:
  ``c_i = (v_i - lo_i) / (hi_i - lo_i)`` for "min" and
  ``c_i = (hi_i - v_i) / (hi_i - lo_i)`` for "max". A metric that is constant
  over the feasible designs contributes 0. With ``normalization="none"`` the
  metrics enter in SI base units (time constant in s, flight time in s,
  inertia in kg m^2), which is how Paper D's case 1 adds them (its Table D.5
  objective 0.312 = 0.27 s + 0.04 kg m^2 ...).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import Literal

import numpy as np

from optimizer.errors import RequestError
from optimizer.model.grid import DesignGrid

Sense = Literal["min", "max"]


@dataclass(frozen=True)
class MetricSpec:
    """A user-facing objective name bound to a grid metric and its sense."""

    name: str
    metric: str
    sense: Sense
    label: str
    unit: str
    #: factor from the grid unit to SI base units (for un-normalised sums)
    to_si: float = 1.0


#: The objective names of the command line (Table E.2 of Paper E).
METRICS: dict[str, MetricSpec] = {
    m.name: m
    for m in (
        MetricSpec("flight-time", "flight_time_min", "max", "flight time", "min", 60.0),
        MetricSpec("time-constant", "time_constant_ms", "min", "time constant", "ms", 1e-3),
        MetricSpec("power", "power_w", "min", "power", "W"),
        MetricSpec("price", "price", "min", "price", ""),
        MetricSpec("roll-inertia", "roll_inertia_kgm2", "min", "roll inertia", "kg m^2"),
        MetricSpec("pitch-inertia", "pitch_inertia_kgm2", "min", "pitch inertia", "kg m^2"),
        MetricSpec("mass", "total_mass_kg", "min", "total mass", "kg"),
    )
}

#: Objective names offered by ``rotorbench optimize --objective`` (plus "weighted").
OBJECTIVE_NAMES: tuple[str, ...] = (
    "flight-time",
    "time-constant",
    "power",
    "price",
    "roll-inertia",
    "pitch-inertia",
)

#: Paper D case 1 (dynamic performance): time constant + roll + pitch inertia, gains 1.
PAPER_D_CASE1_WEIGHTS: dict[str, float] = {
    "time-constant": 1.0,
    "roll-inertia": 1.0,
    "pitch-inertia": 1.0,
}

Normalization = Literal["range", "none"]


@dataclass(frozen=True)
class Objective:
    """A weighted sum of metric terms (a single objective has one term, weight 1)."""

    terms: tuple[tuple[MetricSpec, float], ...]
    normalization: Normalization = "range"

    @property
    def is_single(self) -> bool:
        return len(self.terms) == 1 and self.terms[0][1] == 1.0

    @property
    def name(self) -> str:
        if self.is_single:
            return self.terms[0][0].name
        inner = ",".join(f"{m.name}={w:g}" for m, w in self.terms)
        return f"weighted({inner}; {self.normalization})"

    @property
    def metrics(self) -> tuple[str, ...]:
        return tuple(m.metric for m, _ in self.terms)

    def needs_ranges(self) -> bool:
        return not self.is_single and self.normalization == "range"

    def cost(
        self, grid: DesignGrid, ranges: Mapping[str, tuple[float, float]] | None = None
    ) -> np.ndarray:
        """Cost to minimise on (P, M, B); NaN where a metric is not finite."""
        total = np.zeros(grid.shape)
        for spec, weight in self.terms:
            value = np.broadcast_to(np.asarray(grid.metrics[spec.metric], float), grid.shape)
            if self.is_single:
                term = value if spec.sense == "min" else -value
            elif self.normalization == "range":
                if ranges is None:
                    raise ValueError("weighted objective with range normalisation needs ranges")
                lo, hi = ranges[spec.metric]
                span = hi - lo
                if not np.isfinite(span) or span <= 0:
                    term = np.where(np.isfinite(value), 0.0, np.nan)
                elif spec.sense == "min":
                    term = (value - lo) / span
                else:
                    term = (hi - value) / span
            else:
                si = value * spec.to_si
                term = si if spec.sense == "min" else -si
            total = total + weight * term
        return np.where(np.isfinite(total), total, np.nan)


def single(name: str) -> Objective:
    """The objective for one command-line name, e.g. ``single("flight-time")``."""
    try:
        return Objective(((METRICS[name], 1.0),))
    except KeyError:
        known = ", ".join(METRICS)
        raise RequestError(f"unknown objective {name!r}; expected one of {known}") from None


def weighted(weights: Mapping[str, float], normalization: Normalization = "range") -> Objective:
    """A weighted sum; ``weights`` maps objective names to non-negative weights."""
    if not weights:
        raise RequestError("weighted objective needs at least one weight, e.g. flight-time=1")
    if normalization not in ("range", "none"):
        raise RequestError(f"normalization must be 'range' or 'none', got {normalization!r}")
    terms = []
    for name, weight in weights.items():
        if name not in METRICS:
            known = ", ".join(METRICS)
            raise RequestError(f"unknown metric {name!r} in weights; expected one of {known}")
        if not np.isfinite(weight) or weight < 0:
            raise RequestError(f"weight of {name} must be a finite number >= 0, got {weight}")
        terms.append((METRICS[name], float(weight)))
    if all(w == 0 for _, w in terms):
        raise RequestError("at least one weight must be > 0")
    return Objective(tuple(terms), normalization)


def parse_weights(text: str) -> dict[str, float]:
    """Parse ``"flight-time=0.5,price=0.5"`` into a dict (RequestError on bad syntax)."""
    weights: dict[str, float] = {}
    for part in filter(None, (p.strip() for p in text.split(","))):
        name, sep, value = part.partition("=")
        if not sep:
            raise RequestError(f"bad weight {part!r}; expected NAME=NUMBER, e.g. price=0.5")
        if name.strip() in weights:
            raise RequestError(f"bad weight {part!r}: {name.strip()} is weighted twice")
        try:
            weights[name.strip()] = float(value)
        except ValueError:
            raise RequestError(f"bad weight {part!r}: {value!r} is not a number") from None
    return weights


def metric_ranges(
    grids: Iterable[DesignGrid], feasible: Iterable[np.ndarray], metrics: Iterable[str]
) -> dict[str, tuple[float, float]]:
    """(lo, hi) of each metric over the feasible designs of all grids (NaN if none)."""
    grids = list(grids)
    feasible = list(feasible)
    out: dict[str, tuple[float, float]] = {}
    for metric in metrics:
        lo, hi = np.inf, -np.inf
        for grid, ok in zip(grids, feasible, strict=True):
            value = np.broadcast_to(np.asarray(grid.metrics[metric], float), grid.shape)
            sel = value[ok & np.isfinite(value)]
            if sel.size:
                lo, hi = min(lo, float(sel.min())), max(hi, float(sel.max()))
        out[metric] = (lo, hi) if lo <= hi else (np.nan, np.nan)
    return out
