"""A catalog design as something to fly: its vehicle, its actuator model, its report.

The numbers come from the optimizer's own model grid
(``optimizer.model.design_model.evaluate_grid``, with measured overrides when the grid was
built with them), so the flight model and ``evaluate`` agree on mass, inertia, hover speed
and time constant. Measured actuator numbers, where a ``MeasuredActuator`` carries them,
replace the model's: rising and falling time constants and latency (Paper C), k_f and k_m
(static curves). A step run fitted on the fly arrives as plain numbers (``StepConstants``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from optimizer.catalogs.catalog import Catalog
from optimizer.errors import RequestError
from optimizer.flight.actuators import ActuatorModel
from optimizer.flight.controller import Gains, design_gains, phase_margins
from optimizer.flight.maneuvers import DT_S, HOVER, Maneuver, fly
from optimizer.flight.uncertainty import std_of
from optimizer.flight.vehicle import Vehicle, vehicle_from_grid
from optimizer.model.design_model import ModelGrid
from optimizer.model.grid import DesignGrid


@dataclass(frozen=True)
class StepConstants:
    """Paper C's fitted actuator (e.g. one step run): seconds; frame NaN if unknown."""

    tau_up_s: float
    tau_down_s: float
    latency_s: float
    frame_s: float = math.nan
    source: str = "step run"
    #: the measured actuator's catalog ids, where the run names them
    motor: str | None = None
    propeller: str | None = None


def design_index(grid: DesignGrid, propeller: str, motor: str, battery: str
                 ) -> tuple[int, int, int]:
    """(i, j, k) of the named design in a grid; unknown ids name the catalog's."""
    out = []
    for ids, wanted, kind in ((grid.propeller_ids, propeller, "propeller"),
                              (grid.motor_ids, motor, "motor"),
                              (grid.battery_ids, battery, "battery")):
        if wanted not in ids:
            known = ", ".join(ids[:20]) + (", ..." if len(ids) > 20 else "")
            raise RequestError(f"--{kind} {wanted!r}: not in the catalog (known: {known})")
        out.append(ids.index(wanted))
    return out[0], out[1], out[2]


def setup(catalog: Catalog, grid: ModelGrid, index: tuple[int, int, int], *, layout: str = "x",
          step: StepConstants | None = None, drag_n_s_m: float = 0.0
          ) -> tuple[Vehicle, ActuatorModel]:
    """Vehicle and actuator of design ``index``: model, measured overrides, or a step fit."""
    vehicle = vehicle_from_grid(catalog, grid, index, layout, drag_n_s_m)
    i, j, k = index
    tau = float(grid.metrics["time_constant_ms"][i, j, k]) * 1e-3
    measured = getattr(grid, "overrides", {}).get((i, j))
    source = "model (E.35)"
    masks = getattr(grid, "measured", {})
    if "time_constant_ms" in masks and masks["time_constant_ms"][i, j, k]:
        source = f"measured: run {measured.run_of('time_constant')}" if measured else "measured"
    up = down = tau
    latency = 0.0
    frame = None
    if measured is not None:
        up = measured.tau_up_s or up
        down = measured.tau_down_s or down
        latency = measured.latency_s if measured.latency_s is not None else latency
        vehicle = vehicle.with_constants(k_f=measured.k_f_n_s2, k_m=measured.k_m_nm_s2)
    if step is not None:
        up, down, latency, source = step.tau_up_s, step.tau_down_s, step.latency_s, step.source
        if math.isfinite(step.frame_s):
            frame = step.frame_s
    kwargs: dict[str, Any] = {} if frame is None else {"frame_s": frame}
    return vehicle, ActuatorModel(up, down, latency, source=source, **kwargs)


def design_std(grid: DesignGrid, index: tuple[int, int, int], step: StepConstants | None = None
               ) -> dict[str, float]:
    """The std of each constant ``setup`` flies design ``index`` with
    (``optimizer.flight.uncertainty.QUANTITIES``): the measured override's spreads, 0
    where the constant is the model's; a step run given to ``setup`` replaces the time
    constants and latency and brings no spread."""
    std = std_of(getattr(grid, "overrides", {}).get((index[0], index[1])))
    if step is not None:
        std.update(tau_up_s=0.0, tau_down_s=0.0, latency_s=0.0)
    return std


def gains_for(actuator: ActuatorModel, dt: float = DT_S) -> Gains:
    """The gain rule applied to this actuator (``optimizer.flight.controller``)."""
    return design_gains(actuator.tau_mean_s, actuator.effective_delay_s(dt))


def fly_report(vehicle: Vehicle, actuator: ActuatorModel, maneuvers: list[Maneuver],
               record: dict[str, Any], keep: bool = False) -> tuple[dict[str, Any], dict]:
    """Fly hover and the maneuvers; the JSON report and (``keep``) the ``Flight`` objects."""
    gains = gains_for(actuator)
    hover = fly(vehicle, actuator, HOVER, gains=gains, record=True)
    flights = {"hover": hover} if keep else {}
    out_man = {}
    for man in maneuvers:
        f = fly(vehicle, actuator, man, gains=gains, record=keep)
        out_man[man.name] = f.figures
        if keep:
            flights[man.name] = f
    hov = dict(hover.figures)
    shortfall = vehicle.hover_shortfall()
    report = {
        "design": {key: record.get(key) for key in (
            "actuators", "propeller", "motor", "battery", "feasible", "reason",
            "time_constant_ms", "hover_rpm", "total_mass_kg", "power_w") if key in record},
        # power_w: evaluate's hover power (the model's shaft power, or electrical where
        # measured currents replace it); shaft_power_w: N k_m omega^3 at the trim, where
        # the flown hover settles
        "hover": {"rpm": hov["rpm"], "throttle": hov["throttle"],
                  "power_w": record.get("power_w"), "shaft_power_w": hov["shaft_power_w"],
                  "model_rpm": hov["model_rpm"],
                  "evaluate_hover_rpm": record.get("hover_rpm"),
                  "can_hover": not shortfall, "note": shortfall},
        "maneuvers": out_man,
        "vehicle": {
            "layout": vehicle.layout, "mass_kg": vehicle.mass_kg,
            "inertia_kgm2": list(vehicle.inertia_kgm2), "arm_m": vehicle.arm_m,
            "k_f_n_s2": vehicle.k_f, "k_m_nm_s2": vehicle.k_m,
            "omega_max_rad_s": vehicle.omega_max_rad_s, "drag_n_s_m": vehicle.drag_n_s_m,
        },
        "actuator": {
            "tau_up_ms": actuator.tau_up_s * 1e3, "tau_down_ms": actuator.tau_down_s * 1e3,
            "latency_ms": actuator.latency_s * 1e3, "esc_frame_ms": actuator.frame_s * 1e3,
            "levels": actuator.levels, "idle_fraction": actuator.idle_fraction,
            "source": actuator.source,
        },
        "gains": {**gains.as_dict(), "phase_margins_deg": phase_margins(gains)},
        "rate_hz": 1.0 / DT_S,
    }
    return report, flights


def feasible_indices(grid: DesignGrid, extra_checks: tuple = ()) -> list[tuple[int, int, int]]:
    """Every design of a grid that meets its limit checks, in catalog order."""
    from optimizer.model.grid import meets_checks  # the optimizer's own feasibility rule

    ok = meets_checks(grid, (*grid.checks, *extra_checks))
    return [(int(i), int(j), int(k)) for i, j, k in np.argwhere(ok)]
