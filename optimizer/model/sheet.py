"""One design as eCalc shows it: full throttle, hover throttle, partial load, battery.

``design_sheet`` adds to ``optimizer.model.design_model.evaluate_design``'s record (the thesis'
hover numbers, unchanged) what a designer reads on an eCalc sheet: maximum thrust per
actuator, thrust-to-weight, hover throttle, efficiency, the partial-load table, the
Shepherd-model flight time beside the thesis' constant-voltage one, C-rate checks
(continuous at hover, burst at full throttle) and the margin of every limit.
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import Any

import numpy as np

from optimizer.catalogs.catalog import Catalog
from optimizer.model import battery as bat
from optimizer.model import operating_points as ops
from optimizer.model import physics
from optimizer.model.design_model import battery_voltage_v


def drive_of(catalog: Catalog, coefficients: ops.Coefficients | None = None) -> ops.Drive:
    """The catalog's drives on grid axes: propellers (P,1,1), motors (1,M,1)."""
    props, mots = catalog.propellers, catalog.motors

    def p_(col: str) -> np.ndarray:
        return props[col].to_numpy(float)[:, None, None]

    def m_(col: str) -> np.ndarray:
        return mots[col].to_numpy(float)[None, :, None]

    return ops.Drive(
        ct=p_("ct"),
        cp=p_("cp"),
        diameter_m=p_("diameter_m"),
        kt=physics.torque_constant(m_("kv_rad_s_per_v")),
        resistance_ohm=m_("resistance_ohm"),
        no_load_current_a=np.nan_to_num(m_("no_load_current_a"), nan=0.0),
        rho=catalog.constants.air_density_kg_m3,
        coefficients=coefficients,
        current_model=catalog.constants.current_model,
    )


def pack_of(catalog: Catalog) -> dict[str, np.ndarray]:
    """Battery axis (1,1,B): cells, capacity, resistance, continuous and burst limits."""
    b = catalog.batteries
    cells = b["cells"].to_numpy(float)
    cap = b["capacity_ah"].to_numpy(float)
    given = b["resistance_ohm"].to_numpy(float) if "resistance_ohm" in b else None
    cont = b["max_current_a"].to_numpy(float)
    burst_c = b["burst_c_rating"].to_numpy(float) if "burst_c_rating" in b else np.full_like(
        cap, np.nan
    )
    out = {
        "cells": cells,
        "capacity_ah": cap,
        "resistance_ohm": bat.pack_resistance_ohm(cells, cap, given_ohm=given),
        "continuous_a": cont,
        # no burst rating: the continuous limit is the conservative burst limit
        "burst_a": np.where(np.isnan(burst_c), cont, burst_c * cap),
        "voltage_v": battery_voltage_v(catalog),
    }
    return {k: v[None, None, :] for k, v in out.items()}


def _one(a: Any) -> float:
    return float(np.asarray(a, float).reshape(-1)[0])


def design_sheet(
    single: Catalog,
    record: dict[str, Any],
    curve: bat.CellCurve = bat.DEFAULT_CELL,
    coefficients: ops.Coefficients | None = None,
) -> dict[str, Any]:
    """eCalc-like keys for the one design of ``single`` (a catalog of one row each)."""
    c = single.constants
    n = int(record["actuators"])
    mass = float(record["total_mass_kg"])
    weight = mass * c.gravity_m_s2
    drive = drive_of(single, coefficients)
    pack = pack_of(single)
    v_b = pack["voltage_v"]
    top = ops.at_throttle(drive, 1.0, v_b)
    hover = ops.at_thrust(drive, weight / n, v_b)  # (E.19)-(E.20)
    max_thrust = _one(top.thrust_n)
    model = drive.current_model
    out: dict[str, Any] = {
        "current_model": model,
        "max_thrust_n": max_thrust,
        "thrust_to_weight": n * max_thrust / weight,
        "hover_throttle_pct": 100.0 * _one(hover.throttle),
        "efficiency_g_per_w": _one(hover.efficiency_g_per_w),
        "hover_electric_power_w": n * _one(hover.power_w),
        "hover_battery_current_a": n * _one(hover.battery_current_a),
        # per actuator, battery side, the run's current model: the design's x18 / N
        "hover_current_per_actuator_a": _one(hover.battery_current_a),
        "current_models": _current_models(drive, weight / n, v_b, n, pack["capacity_ah"]),
        "max_rpm": _one(top.rpm),
        "max_motor_current_a": _one(top.motor_current_a),
        "max_battery_current_a": n * _one(top.battery_current_a),
        "max_electric_power_w": n * _one(top.power_w),
        "tip_speed_max_m_s": math.pi * _one(drive.diameter_m) * _one(top.rpm) / 60.0,
        "partial_load": ops.partial_load(
            ops.Drive(**{**drive.__dict__, **_squeeze(drive)}), _one(v_b)
        ),
    }
    dis = bat.discharge(
        n * hover.power_w, pack["cells"], pack["capacity_ah"], pack["resistance_ohm"], curve
    )
    load = ("shaft power, loss-free drive (E.67)" if model == "thesis"
            else "motor electric power, winding loss included")
    out["battery_model"] = {
        "label": "Shepherd discharge (Tremblay 2007), constant hover power to "
        f"{curve.cutoff_v:g} V/cell; hover power: {load}",
        "flight_time_min": _one(dis.time_min),
        "thesis_flight_time_min": float(record["flight_time_min"]),
        "thesis_label": f"constant voltage, whole capacity (E.67-E.74); hover power: {load}",
        "usable_capacity_pct": 100.0 * _one(dis.used_fraction),
        "start_voltage_v": _one(dis.start_voltage_v),
        "end_voltage_v": _one(dis.end_voltage_v),
        "start_current_a": _one(dis.start_current_a),
        "end_current_a": _one(dis.end_current_a),
        "pack_resistance_ohm": _one(pack["resistance_ohm"]),
        "cutoff_cell_v": curve.cutoff_v,
    }
    mot = single.motors.iloc[0]
    limits = [
        # C-rate: the current at the end of the discharge is the highest hover current
        ("battery continuous (hover, end of discharge)", "A", _one(dis.end_current_a),
         _one(pack["continuous_a"])),
        ("battery burst (full throttle)", "A", n * _one(top.battery_current_a),
         _one(pack["burst_a"])),
        ("motor current (full throttle)", "A", _one(top.motor_current_a),
         float(mot["max_current_a"])),
        ("motor power (full throttle, shaft)", "W", _one(top.shaft_power_w),
         float(mot["max_power_w"])),
    ]
    margins = [
        _margin(ch["label"], ch["unit"], ch["value"], ch["limit"], ch["sense"])
        for ch in record.get("checks", [])
    ]
    margins += [_margin(label, unit, v, lim, "<=") for label, unit, v, lim in limits]
    out["limit_margins"] = margins
    return out


CURRENT_MODEL_LABELS = {
    "thesis": "(E.67): the battery delivers the propeller's shaft power at B_V",
    "drive": "the motor's electric power V_m I_w at B_V (winding loss R I_w^2 and I_0)",
}


def _current_models(drive: ops.Drive, thrust_n: float, v_b: Any, n: int,
                    capacity_ah: Any) -> dict[str, dict[str, Any]]:
    """Both current definitions at hover, side by side: per-actuator battery current and
    the constant-voltage flight time 60 B_Ah / x18 (E.72) each gives. The run's own model
    (``current_model``) is the one every other key uses."""
    out = {}
    for name, label in CURRENT_MODEL_LABELS.items():
        hover = ops.at_thrust(replace(drive, current_model=name), thrust_n, v_b)
        current = _one(hover.battery_current_a)
        out[name] = {"label": label, "current_per_actuator_a": current,
                     "flight_time_min": 60.0 * _one(capacity_ah) / (n * current)}
    return out


def _squeeze(drive: ops.Drive) -> dict[str, Any]:
    return {
        k: float(np.asarray(getattr(drive, k)).reshape(-1)[0])
        for k in ("ct", "cp", "diameter_m", "kt", "resistance_ohm", "no_load_current_a")
    }


def _margin(label: str, unit: str, value: float, limit: float, sense: str) -> dict[str, Any]:
    """Signed margin in the limit's unit and percent of the limit (>= 0: satisfied)."""
    diff = limit - value if sense == "<=" else value - limit
    pct = 100.0 * diff / abs(limit) if limit and math.isfinite(limit) else None
    return {"label": label, "unit": unit, "value": value, "limit": limit, "sense": sense,
            "margin": diff, "margin_pct": pct, "ok": bool(diff >= -1e-9 * max(1.0, abs(limit)))}


def hover_shortfall(catalog: Catalog, n: int, propeller: str, motor: str, battery: str,
                    payload_kg: float = 0.0) -> str | None:
    """Why a design the catalog limits accept cannot hover, or None if it can.

    The thesis' model has no thrust limit, so its optimum can need more speed than its motor
    reaches on B_V (thesis-e's exact Case III optimum P1/M1/B3 with 4 actuators: 4994 rpm
    needed, 4279 rpm at full throttle; the thesis' own pick P1/M1/B1 hovers). Full
    throttle is the steady state (E.4)-(E.7), the sheet's ``max_thrust_n``.
    """
    from optimizer.model.design_model import evaluate_grid, single_design_catalog

    single = single_design_catalog(catalog, propeller, motor, battery)
    grid = evaluate_grid(single, n, payload_kg)
    weight = _one(grid.metrics["total_mass_kg"]) * single.constants.gravity_m_s2
    v_b = pack_of(single)["voltage_v"]
    top = ops.at_throttle(drive_of(single), 1.0, v_b)
    ratio = n * _one(top.thrust_n) / weight
    if ratio >= 1.0:
        return None
    return (f"cannot hover: thrust-to-weight {ratio:.2f} at full throttle (needs "
            f"{_one(grid.metrics['hover_rpm']):.0f} rpm, the motor reaches "
            f"{_one(top.rpm):.0f} rpm on {_one(v_b):.3g} V)")


def hover_warnings(catalog: Catalog, designs: Any, payload_kg: float = 0.0) -> list[str]:
    """One line per design (``(actuators, propeller, motor, battery)``) that cannot hover;
    the thesis' limits do not check it (the sizing commands' default
    ``--min-thrust-to-weight``, or ``min_thrust_to_weight`` in catalog.toml, make it a
    limit). Batteries not in the catalog (an S/P pack such as ``B1-4S3P``, built per run)
    are skipped: ``evaluate --battery`` checks them."""
    out = []
    for n, propeller, motor, battery in designs:
        if battery not in catalog.battery_ids:
            continue
        why = hover_shortfall(catalog, n, propeller, motor, battery, payload_kg)
        if why is not None:
            out.append(f"{n} actuators, {propeller}/{motor}/{battery}: {why}; "
                       "--min-thrust-to-weight (the default without --thesis-rules) excludes "
                       "such designs")
    return out
