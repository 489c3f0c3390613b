"""Fly one chunk of designs: the one function a sweep's tasks run.

A task gets numbers (a slice of the plan of ``optimizer.sweep.designs``: keys, static
numbers, flight parameters, measured spreads) and returns rows (``optimizer.sweep.rows``);
it reads no file and keeps no state, so any worker may run it, again after a worker died,
with the same result. The designs fly together (``optimizer.flight.batch.fly_batch``: one
numpy flight per rotor count and layout, figures equal to ``rotorbench fly``'s), with the
gains of their own actuator; a design that fails is a row with its ``error``, never a
failed task.

Robust sweeps (``samples`` > 1): each design with a measured spread flies ``samples``
times, sample 0 its nominal constants and the others drawn from the spreads
(``optimizer.flight.uncertainty.draw_many``) with the design's own seed (a hash of its
keys and the sweep's ``seed``, never a worker's or a chunk's), all with the gains of the
nominal actuator (the controller of the vehicle as built). The row's figures are the
nominal flight's; ``_p05/_p50/_p95`` columns are the percentiles over the samples. A design
without a spread flies once: every sample would be the nominal.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd

from optimizer.flight.batch import DesignBatch, fly_batch
from optimizer.flight.maneuvers import maneuver
from optimizer.flight.uncertainty import design_seeds, draw_many, percentile_columns, varies
from optimizer.sweep.flight_params import STD_PREFIX, flight_of
from optimizer.sweep.keys import DESIGN_KEYS
from optimizer.sweep.rows import STATIC, figure_columns, figure_names, spread_figures

#: a drawn quantity (``optimizer.flight.uncertainty.QUANTITIES``) -> its batch argument
DRAWN = {"tau_up_s": "tau_up_s", "tau_down_s": "tau_down_s", "latency_s": "latency_s",
         "k_f_n_s2": "k_f", "k_m_nm_s2": "k_m"}
#: ``DesignBatch.from_arrays`` argument -> plan column
BATCH = {"mass_kg": "vehicle_mass_kg", "ixx": "vehicle_inertia_roll_kgm2",
         "iyy": "vehicle_inertia_pitch_kgm2", "izz": "vehicle_inertia_yaw_kgm2",
         "arm_m": "vehicle_arm_m", "k_f": "vehicle_k_f", "k_m": "vehicle_k_m",
         "omega_max_rad_s": "vehicle_omega_max_rad_s", "gravity_m_s2": "vehicle_gravity_m_s2",
         "drag_n_s_m": "vehicle_drag_n_s_m", "tau_up_s": "actuator_tau_up_s",
         "tau_down_s": "actuator_tau_down_s", "latency_s": "actuator_latency_s",
         "frame_s": "actuator_frame_s", "levels": "actuator_levels",
         "idle_fraction": "actuator_idle_fraction"}


@dataclass(frozen=True)
class Chunk:
    """Designs to fly (rows of a plan), the maneuvers each flies, and how many samples
    of its measured constants (1: nominal only) drawn with ``seed``."""

    designs: pd.DataFrame
    maneuvers: tuple[str, ...]
    samples: int = 1
    seed: int = 0

    def __len__(self) -> int:
        return len(self.designs)


def fly_chunk(chunk: Chunk) -> list[dict[str, Any]]:
    """One output row per design of the chunk, in the chunk's order."""
    records = chunk.designs.to_dict("records")
    rows = [_row(d, chunk.maneuvers) for d in records]
    groups: dict[tuple[int, str], list[int]] = {}
    for i, (d, row) in enumerate(zip(records, rows, strict=True)):
        if row["error"] is None:
            groups.setdefault((int(d["vehicle_n_rotors"]), str(d["vehicle_layout"])),
                              []).append(i)
    for (n, layout), index in groups.items():
        _fly_group(chunk, chunk.designs.iloc[index], n, layout,
                   [rows[i] for i in index])
    return rows


def _row(design: Mapping[str, Any], maneuvers: Sequence[str]) -> dict[str, Any]:
    """The row of a plan design before it flies: keys, static numbers, its actuator and
    whether it can hover, or the error that keeps it on the ground."""
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
        vehicle, actuator = flight_of(design)  # the models' own checks, and the note
    except Exception as exc:  # one design's failure is its row's error, not the sweep's
        row["error"] = f"{type(exc).__name__}: {exc}"
        return row
    note = vehicle.hover_shortfall()
    row.update({"can_hover": not note, "note": note or None,
                "tau_up_ms": actuator.tau_up_s * 1e3,
                "tau_down_ms": actuator.tau_down_s * 1e3,
                "latency_ms": actuator.latency_s * 1e3})
    return row


def _fly_group(chunk: Chunk, designs: pd.DataFrame, n: int, layout: str,
               rows: list[dict[str, Any]]) -> None:
    """Fly designs of one rotor count and layout (and their samples) into ``rows``."""
    arrays = {arg: designs[col].to_numpy(float) for arg, col in BATCH.items()}
    # the columns by argument name; the checker cannot match a dict's keys to parameters
    nominal = DesignBatch.from_arrays(n, layout, **arrays)  # pyright: ignore[reportArgumentType]
    gains = np.stack([nominal.k_p, nominal.w_i, nominal.k_a], axis=1)
    m = chunk.samples
    drawn = np.zeros(len(designs), bool)
    batch = nominal
    std: dict[str, np.ndarray] = {}
    if m > 1:
        std = {q: designs[STD_PREFIX + q].to_numpy(float) for q in DRAWN}
        drawn = varies(std)
    if drawn.any():
        sub = designs.loc[drawn]
        samples = draw_many({q: arrays[arg][drawn] for q, arg in DRAWN.items()},
                            {q: v[drawn] for q, v in std.items()}, m,
                            design_seeds(sub[list(DESIGN_KEYS)].to_dict("records"),
                                         chunk.seed))
        extra = {arg: np.repeat(a[drawn], m - 1) for arg, a in arrays.items()}
        for q, arg in DRAWN.items():  # samples 1 .. m-1 of each drawn design, in order
            extra[arg] = samples[q][:, 1:].ravel()
        both = {arg: np.concatenate([arrays[arg], extra[arg]]) for arg in arrays}
        all_gains = np.concatenate([gains, np.repeat(gains[drawn], m - 1, axis=0)])
        # the columns by argument name, as above
        batch = DesignBatch.from_arrays(n, layout, gains=all_gains,
                                        **both)  # pyright: ignore[reportArgumentType]
    where = _sample_rows(drawn, m)
    for name in chunk.maneuvers:
        figures = fly_batch(batch, maneuver(name))
        for i, row in enumerate(rows):
            fig = figures[i]
            if "error" in fig:
                row["error"] = row["error"] or f"{name}: {fig['error']}"
                continue
            row.update({f"{name}_{f}": fig.get(f) for f in figure_names(name)})
            if m > 1:
                _percentiles(row, name, [figures[k] for k in where[i]], m)


def _sample_rows(drawn: np.ndarray, m: int) -> list[list[int]]:
    """Per design, the batch rows of its samples: its own row first (the nominal), then
    its m - 1 drawn ones (after all nominal rows, design by design); one row if not drawn."""
    out, nxt = [], len(drawn)
    for i, d in enumerate(drawn):
        if d:
            out.append([i, *range(nxt, nxt + m - 1)])
            nxt += m - 1
        else:
            out.append([i])
    return out


def _percentiles(row: dict[str, Any], name: str, flown: list[dict[str, Any]],
                 m: int) -> None:
    """The ``_p05/_p50/_p95`` of each spread figure over a design's samples (a design
    flown once stands for all ``m``); a sample that failed counts as missing."""
    failed = [fig["error"] for fig in flown if "error" in fig]
    if failed and row["error"] is None:
        row["error"] = f"{name}: a drawn sample did not fly: {failed[0]}"
    copies = m if len(flown) == 1 else 1
    for f in spread_figures(name):
        values = [np.nan if fig.get(f) is None else fig[f] for fig in flown] * copies
        row.update(percentile_columns(f"{name}_{f}", values))
