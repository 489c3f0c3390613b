"""``optimize --max-roll-rise-ms T --from-sweep SWEEP.parquet``: a sweep file's roll step
rise times, mapped onto the optimizer's grids instead of flying candidates.

A file is refused (one line) when it cannot answer the question the flights would: no
``roll_step``, another payload, flight options ``optimize`` does not fly with (layout, drag,
a step run's time constants), several rows per design, or model numbers that are not this
run's grid's (another catalog, current model or ``--measured`` store, whatever its spec
says). The choice itself is ``optimizer.solve.roll_rise``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pyarrow.compute as pc

from optimizer.errors import RequestError
from optimizer.model.grid import METRIC_KEYS, DesignGrid
from optimizer.sweep.sweep_file import DESIGN_KEYS, FLAGS, open_sweep, usable_rows

#: The roll rise time ``optimize --from-sweep`` screens on.
ROLL_RISE = "roll_step_rise_time_ms"
#: Relative difference above which a model number of the file is not this grid's.
MODEL_RTOL = 1e-9


#: Flight options of a sweep's spec (as ``fly --sweep`` writes them) that change the roll
#: rise time but not the model numbers: (key, the value ``optimize`` flies with).
FLIGHT_OPTIONS: tuple[tuple[str, Any], ...] = (
    ("layout", "x"),
    ("drag_n_s_m", 0.0),
    ("step_run", None),
)


@dataclass(frozen=True)
class ScreenedGrid:
    """The file's roll rise time on one grid: NaN where a design did not fly, cannot hover
    or never rose; ``present``: the design has a row in the file."""

    rise_ms: np.ndarray
    present: np.ndarray


@dataclass(frozen=True)
class RollScreen:
    """The roll step rise times of a sweep file, by design, to screen a selection with."""

    source: str
    actuators: np.ndarray
    ids: pd.DataFrame  # propeller, motor, battery
    rise_ms: np.ndarray  # NaN where unusable
    metrics: dict[str, np.ndarray]

    def on_grid(self, grid: DesignGrid) -> ScreenedGrid:
        """The rise times on ``grid``'s (P, M, B) after checking that the file's model
        numbers are this grid's (same catalog, payload, current model, measured data)."""
        rows = np.flatnonzero(self.actuators == grid.n_actuators)
        idx = [pd.Index(list(ids)).get_indexer(self.ids[col].to_numpy()[rows])
               for col, ids in (("propeller", grid.propeller_ids), ("motor", grid.motor_ids),
                                ("battery", grid.battery_ids))]
        inside = (idx[0] >= 0) & (idx[1] >= 0) & (idx[2] >= 0)
        if rows.size and not inside.any():
            raise RequestError(f"--from-sweep {self.source}: none of its {rows.size} designs "
                               f"with {grid.n_actuators} actuators is in this catalog (e.g. "
                               f"{self._name(rows[0])}); was it flown with another catalog?")
        i, j, k = (a[inside] for a in idx)
        rows = rows[inside]
        flat = np.ravel_multi_index((i, j, k), grid.shape)
        if np.unique(flat).size < flat.size:
            raise RequestError(f"--from-sweep {self.source}: several rows per design of "
                               f"{grid.n_actuators} actuators (cells in series/parallel?); "
                               "optimize reads a sweep of the catalog's batteries as they are")
        self._check_model(grid, rows, (i, j, k))
        rise = np.full(grid.shape, np.nan)
        present = np.zeros(grid.shape, bool)
        rise[i, j, k] = self.rise_ms[rows]
        present[i, j, k] = True
        return ScreenedGrid(rise, present)

    def _name(self, row: int) -> str:
        return "/".join(str(self.ids[c].iloc[row]) for c in ("propeller", "motor", "battery"))

    def _check_model(self, grid: DesignGrid, rows: np.ndarray,
                     index: tuple[np.ndarray, ...]) -> None:
        for key in METRIC_KEYS:
            here = np.broadcast_to(np.asarray(grid.metrics[key], float), grid.shape)[index]
            there = self.metrics[key][rows]
            both = np.isfinite(here) & np.isfinite(there)
            off = both & (np.abs(here - there) > MODEL_RTOL * np.maximum(np.abs(here), 1.0))
            if off.any():
                at = int(np.flatnonzero(off)[0])
                raise RequestError(
                    f"--from-sweep {self.source}: {int(off.sum())} of its designs with "
                    f"{grid.n_actuators} actuators have another {key} than this catalog's "
                    f"model (e.g. {self._name(rows[at])}: {there[at]:.6g} in the file, "
                    f"{here[at]:.6g} here); "
                    "was it flown with another catalog, --payload-kg, --current-model or "
                    "--measured?")


def roll_screen(path: Path | str, payload_kg: float) -> RollScreen:
    """The roll step rise times of a sweep file, refused (one line) when the file cannot
    answer ``optimize``'s question: no ``roll_step``, another payload, or flight options
    ``optimize`` does not fly with (layout, drag, a step run's time constants). The model
    numbers are checked per grid (:meth:`RollScreen.on_grid`)."""
    sweep = open_sweep(path, "--from-sweep")
    where = f"--from-sweep {sweep.path}"
    if ROLL_RISE not in sweep.types:
        flown = sorted({c.split("_rise_time_ms")[0] for c in sweep.types
                        if "_rise_time_ms" in c}) or ["none"]
        raise RequestError(f"{where}: no {ROLL_RISE} column (maneuvers in the file: "
                           f"{', '.join(flown)}); fly the sweep with roll_step")
    absent = [k for k in METRIC_KEYS if k not in sweep.types]
    if absent:
        raise RequestError(f"{where}: no {', '.join(absent)} column(s), needed to check the "
                           "file against this catalog's model")
    _check_spec(sweep.spec, payload_kg, where)
    table = sweep.read([*DESIGN_KEYS[:4], *FLAGS, ROLL_RISE, *METRIC_KEYS])
    keep, _ = usable_rows(sweep, table, [ROLL_RISE])
    rise = np.where(keep, sweep.floats(table, ROLL_RISE), np.nan)
    ids = table.select(["propeller", "motor", "battery"]).to_pandas()
    return RollScreen(str(sweep.path), pc.fill_null(table.column("actuators"), -1).to_numpy(),
                      ids, rise, {k: sweep.floats(table, k) for k in METRIC_KEYS})


def _check_spec(spec: dict[str, Any], payload_kg: float, where: str) -> None:
    """Refuse a spec that says the file was flown otherwise than ``optimize`` flies: another
    payload, or an option of ``FLIGHT_OPTIONS`` set to another value (an option the spec
    does not name is not known to differ; the model numbers are checked anyway)."""
    options = spec.get("options") or {}
    if not isinstance(options, dict):
        raise RequestError(f"{where}: the spec's options are not a JSON object")
    said = options.get("payload_kg", spec.get("payload_kg"))
    if said is not None:
        if isinstance(said, bool) or not isinstance(said, int | float):
            raise RequestError(f"{where}: the spec's payload_kg {said!r} is not a number")
        if not math.isclose(float(said), payload_kg, abs_tol=1e-12):
            raise RequestError(f"{where}: flown with a payload of {float(said):g} kg; this "
                               f"run asks for {payload_kg:g} kg (--payload-kg)")
    for key, expected in FLIGHT_OPTIONS:
        if key not in options:
            continue
        value = options[key]
        if value is None and expected == 0.0:  # no drag given: none
            value = 0.0
        if value != expected:
            raise RequestError(f"{where}: flown with {key} = {options[key]!r}; optimize flies "
                               f"the catalog's actuators with {key} = {expected!r}")
