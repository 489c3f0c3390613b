"""Fly one chunk of designs: the one function a sweep's tasks run.

A task gets numbers (a slice of the plan of ``optimizer.sweep.designs``: keys, static
numbers, flight parameters) and returns rows (``optimizer.sweep.rows``); it reads no file
and keeps no state, so any worker may run it, again after a worker died, with the same
result. Each design is flown with ``optimizer.flight.maneuvers.fly`` and the gains of
its actuator, exactly as ``rotorbench fly`` flies it; a design that fails is a row with
its ``error``, never a failed task.

Uncertainty sampling (``--samples M``, not here yet) draws a design's samples from
``numpy.random.default_rng(design["seed"])``: the seed is the design's own
(``optimizer.sweep.keys.design_seed``), never a worker's or a chunk's.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import pandas as pd

from optimizer.flight.design import gains_for
from optimizer.flight.maneuvers import fly, maneuver
from optimizer.sweep.flight_params import flight_of
from optimizer.sweep.keys import DESIGN_KEYS
from optimizer.sweep.rows import STATIC, figure_columns, figure_names


@dataclass(frozen=True)
class Chunk:
    """Designs to fly (rows of a plan) and the maneuvers each flies."""

    designs: pd.DataFrame
    maneuvers: tuple[str, ...]

    def __len__(self) -> int:
        return len(self.designs)


def fly_chunk(chunk: Chunk) -> list[dict[str, Any]]:
    """One output row per design of the chunk, in the chunk's order."""
    return [fly_design(d, chunk.maneuvers) for d in chunk.designs.to_dict("records")]


def fly_design(design: Mapping[str, Any], maneuvers: tuple[str, ...]) -> dict[str, Any]:
    """The row of one plan design: keys, static numbers, its flight's figures or error."""
    row: dict[str, Any] = {"design_id": design["design_id"]}
    row.update({k: design[k] for k in (*DESIGN_KEYS, *STATIC)})
    row.update({"can_hover": None, "note": None, "tau_up_ms": None, "tau_down_ms": None,
                "latency_ms": None})
    row.update(dict.fromkeys(figure_columns(maneuvers)))
    row["error"] = None
    refused = design.get("setup_error")
    if isinstance(refused, str) and refused:  # the flight model refused its numbers
        row["error"] = refused
        return row
    try:
        vehicle, actuator = flight_of(design)
        note = vehicle.hover_shortfall()
        row.update({"can_hover": not note, "note": note or None,
                    "tau_up_ms": actuator.tau_up_s * 1e3,
                    "tau_down_ms": actuator.tau_down_s * 1e3,
                    "latency_ms": actuator.latency_s * 1e3})
        gains = gains_for(actuator)
        flown = {m: fly(vehicle, actuator, maneuver(m), gains=gains, record=False).figures
                 for m in maneuvers}
    except Exception as exc:  # one design's failure is its row's error, not the sweep's
        row["error"] = f"{type(exc).__name__}: {exc}"
        return row
    for m, figures in flown.items():
        row.update({f"{m}_{f}": figures.get(f) for f in figure_names(m)})
    return row
