"""The flight parameters of many catalog designs at once, as ``setup`` makes them one by one.

A sweep's plan needs every design's vehicle and actuator as numbers
(``optimizer.sweep.flight_params``). ``optimizer.flight.design.setup`` builds them for one
design (pandas row look-ups, two dataclasses: about a millisecond), which made the plan of
the SizingLab flyable set a serial minute before any flying. Here the model's numbers of
all designs come from arrays in one go, by the same formulas in the same order
(``optimizer.flight.vehicle.vehicle_from_grid``: take-off mass, inertias E.58-E.59, arm
D.4, k_f and k_m from E.1-E.3, full-throttle speed E.4-E.7; an actuator of the model's
time constant E.35); designs with measured numbers (overrides of the grid) or a step run
are left to ``setup`` (tested equal).
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pandas as pd

from optimizer.catalogs.catalog import Catalog
from optimizer.flight.actuators import (
    DEFAULT_FRAME_RATE_HZ,
    DEFAULT_IDLE_FRACTION,
    DEFAULT_LATENCY_S,
    DEFAULT_LEVELS,
)
from optimizer.flight.vehicle import FLIGHT_ACTUATORS, LAYOUTS
from optimizer.model import physics
from optimizer.model.design_model import ModelGrid
from optimizer.sweep.flight_params import INERTIA_COLUMNS, param_columns

#: the actuator source ``setup`` names for the model's time constant
MODEL_SOURCE = "model (E.35)"


def modelled(grid: ModelGrid, idx: np.ndarray, step: Any = None) -> np.ndarray:
    """Which designs (rows of ``idx``) fly the model's numbers alone: no measured override
    of their actuator, no measured time constant, no step run."""
    if step is not None:
        return np.zeros(len(idx), bool)
    ii, jj, kk = idx[:, 0], idx[:, 1], idx[:, 2]
    overrides = getattr(grid, "overrides", {})
    ok = np.array([(i, j) not in overrides for i, j in zip(ii.tolist(), jj.tolist(),
                                                             strict=True)], bool)
    masks = getattr(grid, "measured", {})
    if "time_constant_ms" in masks:
        ok &= ~np.asarray(masks["time_constant_ms"])[ii, jj, kk]
    return ok


def model_params(catalog: Catalog, grid: ModelGrid, idx: np.ndarray, layout: str = "x",
                 drag_n_s_m: float = 0.0) -> pd.DataFrame:
    """``params_of(*setup(...))`` of each design ``idx`` (n, 3) from the model alone, one
    row each, and a bool column ``valid``: the numbers ``Vehicle`` would accept (the
    others are for ``setup`` to refuse with its message)."""
    ii, jj, kk = idx[:, 0], idx[:, 1], idx[:, 2]
    props, mots, c = catalog.propellers, catalog.motors, catalog.constants
    ct = props["ct"].to_numpy(float)[ii]
    cp = props["cp"].to_numpy(float)[ii]
    d = props["diameter_m"].to_numpy(float)[ii]
    rho = c.air_density_kg_m3
    roll = grid.metrics["roll_inertia_kgm2"][ii, jj, kk].astype(float)
    pitch = grid.metrics["pitch_inertia_kgm2"][ii, jj, kk].astype(float)
    voltage = np.broadcast_to(grid.extras["voltage_v"], grid.shape)[ii, jj, kk]
    kt = physics.torque_constant(mots["kv_rad_s_per_v"].to_numpy(float)[jj])
    omega_max = physics.full_throttle_speed_rad_s(
        voltage, kt, mots["resistance_ohm"].to_numpy(float)[jj], cp, rho, d)
    n = len(idx)
    pids = np.asarray(grid.propeller_ids, dtype=object)[ii]
    mids = np.asarray(grid.motor_ids, dtype=object)[jj]
    bids = np.asarray(grid.battery_ids, dtype=object)[kk]
    tau = grid.metrics["time_constant_ms"][ii, jj, kk].astype(float) * 1e-3
    values: dict[str, Any] = {
        "vehicle_mass_kg": grid.metrics["total_mass_kg"][ii, jj, kk].astype(float),
        "vehicle_n_rotors": np.full(n, grid.n_actuators),
        "vehicle_arm_m": np.broadcast_to(grid.extras["arm_length_m"], grid.shape)[ii, jj, kk],
        "vehicle_layout": np.full(n, layout, dtype=object),
        "vehicle_k_f": physics.thrust_per_omega2(ct, rho, d),
        "vehicle_k_m": physics.torque_per_omega2(cp, rho, d),
        "vehicle_omega_max_rad_s": omega_max,
        "vehicle_gravity_m_s2": np.full(n, c.gravity_m_s2),
        "vehicle_drag_n_s_m": np.full(n, drag_n_s_m),
        "vehicle_label": [f"{grid.n_actuators}x {p}+{m}+{b}"
                          for p, m, b in zip(pids, mids, bids, strict=True)],
        INERTIA_COLUMNS[0]: roll,
        INERTIA_COLUMNS[1]: pitch,
        INERTIA_COLUMNS[2]: roll + pitch,
        "actuator_tau_up_s": tau,
        "actuator_tau_down_s": tau,
        "actuator_latency_s": np.full(n, DEFAULT_LATENCY_S),
        "actuator_frame_s": np.full(n, 1.0 / DEFAULT_FRAME_RATE_HZ),
        "actuator_levels": np.full(n, DEFAULT_LEVELS),
        "actuator_idle_fraction": np.full(n, DEFAULT_IDLE_FRACTION),
        "actuator_source": np.full(n, MODEL_SOURCE, dtype=object),
    }
    frame = pd.DataFrame({col: values[col] for col in param_columns()})
    positive = [np.asarray(values[k], float) for k in (
        "vehicle_mass_kg", "vehicle_arm_m", "vehicle_k_f", "vehicle_k_m",
        "vehicle_omega_max_rad_s", *INERTIA_COLUMNS, "actuator_tau_up_s")]
    frame["valid"] = (np.logical_and.reduce([np.isfinite(v) & (v > 0) for v in positive])
                      & (grid.n_actuators in FLIGHT_ACTUATORS) & (layout in LAYOUTS)
                      & (c.gravity_m_s2 > 0) & np.isfinite(drag_n_s_m))
    return frame
