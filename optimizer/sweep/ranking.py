"""The time constant ranking (``optimizer.flight.ranking``) computed from a sweep's rows.

``rotorbench fly --sweep`` without ``--out`` and :func:`rank` fly every feasible design
through ``roll_step`` with the sweep engine and read the ranking off its rows: one way
to fly a catalog, whoever asks.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterable, Mapping
from typing import Any

from optimizer.catalogs.catalog import Catalog
from optimizer.flight.ranking import FlownDesign, Ranking, spearman
from optimizer.model.design_model import ModelGrid
from optimizer.sweep.chunks import split
from optimizer.sweep.designs import grid_designs
from optimizer.sweep.fly_rows import fly_chunk

#: the maneuver the ranking reads
MANEUVER = "roll_step"
#: designs per batch flight of ``rank`` (progress after each)
RANK_CHUNK = 256


def flown_design(row: Mapping[str, Any], battery: str | None = None) -> FlownDesign:
    """One sweep row (flown through ``roll_step``) as a ranking row; ``battery`` names
    the battery where the row's key alone does not (a pack: ``B1-4S2P``). A design that
    did not fly is listed with its error as the note (left out of rho, as one that
    cannot hover)."""
    fig = {k[len(MANEUVER) + 1:]: v for k, v in row.items() if k.startswith(MANEUVER + "_")}
    note = f"did not fly: {row['error']}" if row["error"] else row["note"] or ""

    def number(value: Any) -> float:
        return math.nan if value is None else value

    return FlownDesign(
        row["propeller"], row["motor"], battery or row["battery"], row["time_constant_ms"],
        fig["rise_time_ms"], number(fig["overshoot_pct"]), fig["settling_time_ms"],
        number(fig["saturation_pct"]), number(row["tau_up_ms"]), number(row["tau_down_ms"]),
        number(fig["final_error_pct"]), note)


def ranking_from_rows(actuators: int, rows: Iterable[Mapping[str, Any]], seconds: float,
                      packs: bool = False) -> Ranking:
    """The ranking of one actuator count's rows; ``packs``: batteries are named by their
    pack (``cell-SxP``, as ``optimizer.solve.packs.pack_frame`` names them)."""
    out = [flown_design(r, f"{r['battery']}-{r['series']}S{r['parallel']}P" if packs
                        else None) for r in rows]
    rho, p = spearman(out)
    return Ranking(actuators, out, rho, p, seconds)


def rank(catalog: Catalog, grid: ModelGrid, progress: Callable[[int, int], None] | None = None,
         **setup_kwargs: Any) -> Ranking:
    """Fly every feasible design of ``grid`` through ``roll_step`` (in this process, in
    batch flights of ``RANK_CHUNK`` designs, ``progress`` told after each); Spearman rho
    of time constant vs rise time. A design that never reaches 90 % of the step ranks
    last (rise time infinite); one that cannot hover is flown and listed but left out of
    rho. ``setup_kwargs`` go to ``optimizer.flight.design.setup``."""
    start = time.perf_counter()
    plan = grid_designs(catalog, grid, **setup_kwargs)
    rows = []
    for chunk in split(plan, (MANEUVER,), RANK_CHUNK):
        rows += fly_chunk(chunk)
        if progress is not None:
            progress(len(rows), len(plan))
    return ranking_from_rows(grid.n_actuators, rows, time.perf_counter() - start)
