"""The design model: every metric of every (propeller, motor, battery) design at hover.

``evaluate_grid`` fills an ``optimizer.model.grid.DesignGrid`` for one actuator count and
payload with numpy broadcasting over the axes (P, M, B); ``evaluate_design`` reads one
design out of it. The physics is Papers D and E (see ``optimizer.model.physics``); the open
readings of the printed equations are catalog constants (``optimizer.catalogs.model_constants``).
One actuator's chain from its thrust to speed, power, current and time constant is
``hover_actuator``, run by ``evaluate_grid`` on every design and by ``actuator_at_thrust``
on one propeller and motor at any thrust (what a bench measurement is compared with).
(Named ``design_model`` to set it apart from ``optimizer.solve.milp_builder``, which builds MILPs.)

Metric definitions (all at hover, the operating point of Paper E's flight time):
- ``propeller_power_w``: power of one propeller, x17 (E.61-E.63).
- ``power_w``: total hover power drawn from the battery, B_V x18: N x17 with the thesis'
  current (E.67), the motors' electric power with ``current_model = "drive"``. This is
  what the "min power" objective minimises. Table E.2 literally minimises x17; for a
  fixed actuator count (each thesis MILP has a fixed N) both pick the same design.
- ``current_a``: battery current, x18 (E.67-E.69), or N V_m I_w / B_V with
  ``current_model = "drive"`` (``ModelConstants.current_model``: one definition per run).
- ``extras["motor_current_a"]``: winding current per motor, Q / K_t + I_0 with the
  hover torque Q = W / omega (E.3), (E.5)-(E.7); checked against the motor's
  ``max_current_a`` ("motor winding current") unless ``motor_current = "battery"``.
- ``flight_time_min``: 60 B_Ah / x18 (E.72-E.74 inverted).
- ``time_constant_ms``: (E.35) at the design's hover speed.
- ``total_mass_kg``: take-off mass incl. payload, x1 + m_L (E.17, E.19).
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from optimizer.catalogs.catalog import Catalog
from optimizer.errors import RequestError
from optimizer.model import physics
from optimizer.model.grid import METRIC_KEYS, Check, DesignGrid
from optimizer.model.measured import MeasuredActuator, select_overrides
from optimizer.model.operating_points import Coefficients, Drive, at_throttle, speed_for_thrust


@dataclass(frozen=True)
class ModelGrid(DesignGrid):
    """A ``DesignGrid`` plus which cells hold measured rather than modelled values.

    ``measured[key]`` is a boolean (P, M, B) mask for each metric that has at least one
    measured cell; metrics not in the mapping are modelled everywhere. ``extras`` holds
    intermediate quantities (hover thrust, voltage, frame mass, ...) for reports.
    ``overrides`` maps (propeller index, motor index) to the ``MeasuredActuator`` used
    there (``design_sources`` names its runs).
    """

    measured: dict[str, np.ndarray] = field(default_factory=dict)
    extras: dict[str, np.ndarray] = field(default_factory=dict)
    overrides: dict[tuple[int, int], MeasuredActuator] = field(default_factory=dict)


#: A payload beyond this is a typo, not a multirotor (1e308 kg overflowed numpy on the way).
MAX_PAYLOAD_KG = 1e4


def _check_request(n_actuators: Any, payload_kg: Any) -> tuple[int, float]:
    if isinstance(n_actuators, bool) or not isinstance(n_actuators, int | np.integer):
        raise RequestError(f"actuators: expected a whole number >= 3, got {n_actuators!r}")
    if n_actuators < 3:
        raise RequestError(f"actuators: expected a whole number >= 3, got {n_actuators}")
    try:
        payload = float(payload_kg)
    except (TypeError, ValueError):
        raise RequestError(f"payload: expected a number of kg >= 0, got {payload_kg!r}") from None
    if not math.isfinite(payload) or not 0 <= payload <= MAX_PAYLOAD_KG:
        raise RequestError(f"payload: expected a number of kg from 0 to {MAX_PAYLOAD_KG:g}, "
                           f"got {payload_kg!r}")
    return int(n_actuators), payload


def propeller_inertia_kgm2(catalog: Catalog) -> np.ndarray:
    """J_p per propeller: ``inertia_kgm2`` or k m D^2 (k = propeller_inertia_coefficient)."""
    props = catalog.propellers
    given = props["inertia_kgm2"].to_numpy(float)
    k = catalog.constants.propeller_inertia_coefficient
    estimate = k * props["mass_kg"].to_numpy(float) * props["diameter_m"].to_numpy(float) ** 2
    return np.where(np.isnan(given), estimate, given)


def motor_inertia_kgm2(catalog: Catalog) -> np.ndarray:
    """J_m per motor: ``inertia_kgm2``, else the rotor tube of Table E.5, else 0."""
    mot = catalog.motors
    given = mot["inertia_kgm2"].to_numpy(float)
    rotor = physics.hollow_rotor_inertia_kgm2(
        mot["rotor_diameter_m"].to_numpy(float),
        mot["rotor_length_m"].to_numpy(float),
        mot["rotor_wall_m"].to_numpy(float),
        mot["rotor_density_kg_m3"].to_numpy(float),
    )
    # Neither inertia nor rotor geometry: the rotor inertia is unknown and left out (0).
    return np.where(np.isnan(given), np.nan_to_num(rotor, nan=0.0), given)


def battery_voltage_v(catalog: Catalog) -> np.ndarray:
    """B_V per battery as used in (E.67), following ``constants.battery_voltage``."""
    c = catalog.constants
    bat = catalog.batteries
    cells = bat["cells"].to_numpy(float)
    if c.battery_voltage == "in_flight":
        return cells * c.cell_voltage_in_flight_v  # Paper D section 2.1
    nominal = bat["nominal_voltage_v"].to_numpy(float)
    return np.where(np.isnan(nominal), cells * c.cell_voltage_nominal_v, nominal)


@dataclass(frozen=True)
class HoverActuator:
    """One actuator (or a grid of them, arrays broadcast) delivering a thrust: Paper E's
    chain from the thrust to the speed, power, currents and time constant."""

    n_rev_s: Any  # (E.20) speed, rev/s
    ct: Any  # C_t at that speed (the constant without measured coefficients)
    cp: Any  # C_p at that speed
    propeller_power_w: Any  # (E.60)-(E.63) x17
    #: battery current per actuator: (E.67) x18 / N_a, or the drive's (``current_model``)
    current_a: Any
    torque_nm: Any  # (E.3) shaft torque Q = W / omega
    winding_current_a: Any  # (E.5)-(E.7) Q / K_t + I_0
    electric_power_w: Any  # V_m I_w, V_m = K_e omega + R I_w (E.4)
    time_constant_s: Any  # (E.34)-(E.35)


def hover_actuator(thrust_n: Any, ct: Any, cp: Any, rho: float, diameter_m: Any,
                   resistance_ohm: Any, inertia_kgm2: Any, kt: Any, voltage_v: Any,
                   no_load_current_a: Any = 0.0,
                   coefficients: Coefficients | None = None,
                   current_model: str = "thesis") -> HoverActuator:
    """Paper E's actuator at ``thrust_n``: (E.20) speed, (E.60)-(E.63) power, (E.67)
    current, (E.3), (E.5)-(E.7) torque and winding current, (E.34)-(E.35) time constant.

    The one home of that chain: ``evaluate_grid`` runs it on the whole design grid,
    ``actuator_at_thrust`` on one propeller and motor (the demo's model column).
    ``coefficients`` (rpm -> C_t, C_p) replace the constant coefficients at the speed.
    ``current_model`` (``ModelConstants.current_model``) says what the battery delivers:
    the shaft power (E.67, "thesis") or the motor's electric power ("drive").
    """
    n_rev_s, ct, cp = speed_for_thrust(thrust_n, ct, cp, rho, diameter_m, coefficients)
    power = physics.propeller_power_w(cp, rho, n_rev_s, diameter_m)  # (E.60)-(E.63)
    torque = physics.hover_torque_nm(power, n_rev_s)  # (E.3) Q = W / omega
    damping = physics.propeller_damping(cp, rho, n_rev_s, diameter_m)  # (E.34)
    winding = physics.winding_current_a(torque, kt, no_load_current_a)  # (E.5)-(E.7)
    # (E.4) V_m = K_e omega + R I_w with K_e = K_t in SI units
    electric = (kt * physics.TWO_PI * n_rev_s + resistance_ohm * winding) * winding
    if current_model == "thesis":
        current = power / voltage_v  # (E.67): x18 / N_a per actuator
    elif current_model == "drive":
        current = electric / voltage_v  # V_b I_b = V_m I_w (lossless ESC)
    else:
        raise ValueError(f"current_model: expected 'thesis' or 'drive', got {current_model!r}")
    return HoverActuator(
        n_rev_s=n_rev_s, ct=ct, cp=cp, propeller_power_w=power,
        current_a=current,
        torque_nm=torque,
        winding_current_a=winding,
        electric_power_w=electric,
        time_constant_s=physics.time_constant_s(resistance_ohm, inertia_kgm2, kt, damping),
    )


@dataclass(frozen=True)
class ActuatorPoint:
    """The model's numbers of one propeller on one motor at a thrust and supply voltage."""

    thrust_n: float
    voltage_v: float
    hover: HoverActuator
    top_thrust_n: float  # (E.1) at the full-throttle speed of (E.4)-(E.7)


def actuator_at_thrust(catalog: Catalog, propeller: int, motor: int, thrust_n: float,
                       voltage_v: float) -> ActuatorPoint:
    """The datasheet model of propeller ``propeller`` on motor ``motor`` (catalog indices)
    at ``thrust_n`` per actuator on ``voltage_v``: what a bench measurement of that
    actuator is compared with (the demo's "measured vs datasheet model" table)."""
    c = catalog.constants
    rho = c.air_density_kg_m3
    prop, mot = catalog.propellers.iloc[propeller], catalog.motors.iloc[motor]
    d, ct, cp = (float(prop[k]) for k in ("diameter_m", "ct", "cp"))
    kt = physics.torque_constant(float(mot["kv_rad_s_per_v"]))
    r = float(mot["resistance_ohm"])
    inertia = propeller_inertia_kgm2(catalog)[propeller] + motor_inertia_kgm2(catalog)[motor]
    no_load = float(np.nan_to_num(float(mot["no_load_current_a"]), nan=0.0))
    hover = hover_actuator(thrust_n, ct, cp, rho, d, r, inertia, kt, voltage_v, no_load,
                           current_model=c.current_model)
    top = physics.full_throttle_thrust_n(voltage_v, kt, r, ct, cp, rho, d)
    return ActuatorPoint(float(thrust_n), float(voltage_v), hover, float(top))


def evaluate_grid(
    catalog: Catalog,
    n_actuators: int,
    payload_kg: float = 0.0,
    *,
    overrides: Iterable[MeasuredActuator] | None = None,
    esc_mode: str | None = None,
    coefficients: Coefficients | None = None,
) -> ModelGrid:
    """All metrics and limit checks of every design with ``n_actuators`` actuators.

    ``overrides`` replace the modelled time constant and hover current of given
    (propeller, motor[, ``esc_mode``]) pairs; ``ModelGrid.measured`` says where.
    ``coefficients`` (rpm -> C_t, C_p on the propeller axis, ``optimizer.model.propdata``)
    replace the constant coefficients at hover (opt-in; the thesis uses constants).
    """
    n, payload = _check_request(n_actuators, payload_kg)
    c = catalog.constants
    props, mots, bats = catalog.propellers, catalog.motors, catalog.batteries
    rho, g = c.air_density_kg_m3, c.gravity_m_s2

    # Axis layout: propellers (P,1,1), motors (1,M,1), batteries (1,1,B).
    def p_(col: str) -> np.ndarray:
        return props[col].to_numpy(float)[:, None, None]

    def m_(col: str) -> np.ndarray:
        return mots[col].to_numpy(float)[None, :, None]

    def b_(col: str) -> np.ndarray:
        return bats[col].to_numpy(float)[None, None, :]

    diameter, ct, cp = p_("diameter_m"), p_("ct"), p_("cp")
    m_prop, m_motor, m_batt = p_("mass_kg"), m_("mass_kg"), b_("mass_kg")
    j_prop = propeller_inertia_kgm2(catalog)[:, None, None]
    j_total = j_prop + motor_inertia_kgm2(catalog)[None, :, None]
    resistance = m_("resistance_ohm")
    kt = physics.torque_constant(m_("kv_rad_s_per_v"))
    voltage = battery_voltage_v(catalog)[None, None, :]
    capacity_ah = b_("capacity_ah")

    arm = physics.arm_length_m(diameter, n, c.propeller_clearance_m, c.arm_length)  # (D.4)
    frame = physics.frame_mass_kg(arm, n, c.frame_linear_density_kg_m)  # (E.26)
    actuator_mass = m_prop + m_motor
    # (E.16)-(E.17) total weight; (E.19) plus payload m_L.
    total_mass = n * actuator_mass + frame + m_batt + payload
    hover_thrust = total_mass * g / n  # (E.19)-(E.20), per propeller
    no_load = np.nan_to_num(m_("no_load_current_a"), nan=0.0)  # I_0, 0 where not given
    hover = hover_actuator(hover_thrust, ct, cp, rho, diameter, resistance, j_total, kt,
                           voltage, no_load, coefficients, c.current_model)
    n_rev_s, prop_power, torque = hover.n_rev_s, hover.propeller_power_w, hover.torque_nm
    actuator_current, winding_current = hover.current_a, hover.winding_current_a
    tau = hover.time_constant_s
    shape = (len(props), len(mots), len(bats))
    tau = np.broadcast_to(tau, shape)
    actuator_current = np.broadcast_to(actuator_current, shape)

    measured: dict[str, np.ndarray] = {}
    by_index: dict[tuple[int, int], MeasuredActuator] = {}
    chosen = select_overrides(overrides, esc_mode)
    if chosen:
        tau, actuator_current, measured, by_index = _apply_overrides(
            catalog,
            chosen,
            tau,
            actuator_current,
            np.broadcast_to(hover_thrust, shape),
            np.broadcast_to(voltage, shape),
        )

    current = n * actuator_current  # (E.69) x18
    flight_time_min = 60.0 * capacity_ah / current  # (E.72)-(E.74), inverted
    power = current * voltage  # N x17 when modelled

    prop_price = p_("price") if c.price_includes_propellers else 0.0
    price = n * (prop_price + m_("price")) + b_("price")  # (E.18)

    roll_sum, pitch_sum = physics.arm_axis_sums(n)  # (E.42)-(E.45)
    arm_tube_mass = c.frame_linear_density_kg_m * arm
    roll = physics.body_inertia_kgm2(actuator_mass, arm_tube_mass, arm, roll_sum)  # (E.58)
    pitch = physics.body_inertia_kgm2(actuator_mass, arm_tube_mass, arm, pitch_sum)  # (E.59)

    def full(a: Any) -> np.ndarray:
        return np.ascontiguousarray(np.broadcast_to(np.asarray(a, float), shape))

    metrics = {
        "flight_time_min": full(flight_time_min),
        "time_constant_ms": full(tau * 1e3),
        "price": full(price),
        "total_mass_kg": full(total_mass),
        "hover_rpm": full(n_rev_s * 60.0),
        "propeller_power_w": full(prop_power),
        "power_w": full(power),
        "current_a": full(current),
        "roll_inertia_kgm2": full(roll),
        "pitch_inertia_kgm2": full(pitch),
    }

    winding_current = full(winding_current)
    # Motor power: the thesis compares the propeller (shaft) power with max_power_w
    # (Paper D section 2.4); kept, see docs/optimizer.md "Motor limits".
    checks = [Check("motor power", "W", metrics["propeller_power_w"], m_("max_power_w"))]
    if c.motor_current == "winding":
        # the motor's current rating limits its winding current I_w = Q / K_t + I_0
        checks.append(Check("motor winding current", "A", winding_current, m_("max_current_a")))
    checks += [
        # (E.67) x18 / N: the thesis' motor current check (battery side, per actuator)
        Check("motor current", "A", full(actuator_current), m_("max_current_a")),
        Check("battery current", "A", metrics["current_a"], b_("max_current_a")),
    ]
    top = _measured_top_thrust(by_index, shape, np.broadcast_to(voltage, shape))
    if top is not None:
        # the sweep saw this actuator top out below the hover thrust: it cannot hover
        checks.append(Check("measured max thrust", "N", full(hover_thrust), top))
    extras = {
        "hover_thrust_n": full(hover_thrust),
        "voltage_v": full(voltage),
        "frame_mass_kg": full(frame),
        "arm_length_m": full(arm),
        "hover_torque_nm": full(torque),
        "motor_current_a": winding_current,
    }
    if c.min_thrust_to_weight is not None:
        # full throttle (E.4)-(E.7) with I_0, thrust (E.1): the point of ``evaluate``'s
        # sheet, so the limit and the sheet's thrust_to_weight are one number
        drive = Drive(ct=ct, cp=cp, diameter_m=diameter, kt=kt, resistance_ohm=resistance,
                      no_load_current_a=no_load, rho=rho, coefficients=coefficients,
                      current_model=c.current_model)
        ratio = full(at_throttle(drive, 1.0, voltage).thrust_n / hover_thrust)
        extras["thrust_to_weight"] = ratio
        checks.append(
            Check("thrust to weight", "", ratio, np.asarray(c.min_thrust_to_weight), ">=")
        )

    notes = {
        "source": catalog.source,
        "battery_voltage": c.battery_voltage,
        "arm_length": c.arm_length,
        "motor_current": c.motor_current,
        "current_model": c.current_model,
        "power_w": ("total hover power of all propellers (N x17, Table E.2 'min power')"
                    if c.current_model == "thesis" else
                    "total electric hover power of all motors (N V_m I_w, winding loss "
                    "included)"),
        "total_mass_kg": "take-off mass including payload",
    }
    if np.any(
        np.isnan(catalog.motors["inertia_kgm2"]) & np.isnan(catalog.motors["rotor_diameter_m"])
    ):
        notes["motor_inertia"] = "some motors have neither inertia_kgm2 nor rotor geometry: J_m = 0"
    return ModelGrid(
        n_actuators=n,
        payload_kg=payload,
        propeller_ids=catalog.propeller_ids,
        motor_ids=catalog.motor_ids,
        battery_ids=catalog.battery_ids,
        metrics=metrics,
        checks=tuple(checks),
        notes=notes,
        measured=measured,
        extras=extras,
        overrides=by_index,
    )


def _measured_top_thrust(
    by_index: dict[tuple[int, int], MeasuredActuator],
    shape: tuple[int, int, int],
    voltage: np.ndarray,
) -> np.ndarray | None:
    """Limit array of the "measured max thrust" check: the sweep's top thrust where it
    applies (see ``optimizer.model.measured``), +inf (no limit) elsewhere; None if no sweep."""
    limit = np.full(shape, np.inf)
    for (i, j), item in by_index.items():
        top = item.top_thrust_n
        if top is not None:
            limit[i, j, :] = np.where(item.top_thrust_applies(voltage[i, j, :]), top, np.inf)
    return limit if np.isfinite(limit).any() else None


def _apply_overrides(
    catalog: Catalog,
    chosen: dict[tuple[str, str], MeasuredActuator],
    tau: np.ndarray,
    actuator_current: np.ndarray,
    hover_thrust: np.ndarray,
    voltage: np.ndarray,
) -> tuple[
    np.ndarray, np.ndarray, dict[str, np.ndarray], dict[tuple[int, int], MeasuredActuator]
]:
    p_index = {pid: i for i, pid in enumerate(catalog.propeller_ids)}
    m_index = {mid: i for i, mid in enumerate(catalog.motor_ids)}
    tau = tau.copy()
    actuator_current = actuator_current.copy()
    tau_mask = np.zeros(tau.shape, bool)
    cur_mask = np.zeros(tau.shape, bool)
    by_index: dict[tuple[int, int], MeasuredActuator] = {}
    for (pid, mid), item in chosen.items():
        if pid not in p_index:
            raise RequestError(
                f"overrides: unknown propeller id {pid!r} in catalog {catalog.source}"
            )
        if mid not in m_index:
            raise RequestError(f"overrides: unknown motor id {mid!r} in catalog {catalog.source}")
        i, j = p_index[pid], m_index[mid]
        by_index[(i, j)] = item
        if item.time_constant_s is not None:
            tau[i, j, :] = item.time_constant_s
            tau_mask[i, j, :] = True
        if item.has_current:
            value, inside = item.current_at(hover_thrust[i, j, :], voltage[i, j, :])
            # no extrapolation: outside the measured thrusts the model's current stays
            actuator_current[i, j, :] = np.where(inside, value, actuator_current[i, j, :])
            cur_mask[i, j, :] = inside
    measured: dict[str, np.ndarray] = {}
    if tau_mask.any():
        measured["time_constant_ms"] = tau_mask
    if cur_mask.any():
        for key in ("current_a", "power_w", "flight_time_min"):
            measured[key] = cur_mask
    return tau, actuator_current, measured, by_index


def _index(ids: tuple[str, ...], wanted: str, kind: str, catalog: Catalog) -> int:
    try:
        return ids.index(str(wanted))
    except ValueError:
        known = ", ".join(ids[:20]) + (", ..." if len(ids) > 20 else "")
        raise RequestError(
            f"unknown {kind} id {wanted!r} in catalog {catalog.source} (known: {known})"
        ) from None


def single_design_catalog(
    catalog: Catalog, propeller_id: str, motor_id: str, battery_id: str
) -> Catalog:
    """The catalog of one propeller, motor and battery (ids checked, constants kept)."""
    i = _index(catalog.propeller_ids, propeller_id, "propeller", catalog)
    j = _index(catalog.motor_ids, motor_id, "motor", catalog)
    k = _index(catalog.battery_ids, battery_id, "battery", catalog)
    return Catalog(
        catalog.propellers.iloc[[i]].reset_index(drop=True),
        catalog.motors.iloc[[j]].reset_index(drop=True),
        catalog.batteries.iloc[[k]].reset_index(drop=True),
        catalog.constants,
        catalog.source,
    )


def evaluate_design(
    catalog: Catalog,
    n_actuators: int,
    propeller_id: str,
    motor_id: str,
    battery_id: str,
    payload_kg: float = 0.0,
    *,
    overrides: Iterable[MeasuredActuator] | None = None,
    esc_mode: str | None = None,
) -> dict[str, Any]:
    """One design's metrics, feasibility and violated checks (JSON-ready dict)."""
    single = single_design_catalog(catalog, propeller_id, motor_id, battery_id)
    grid = evaluate_grid(
        single, n_actuators, payload_kg, overrides=_relevant(overrides, single), esc_mode=esc_mode
    )
    return design_record(grid, 0, 0, 0)


def _relevant(
    overrides: Iterable[MeasuredActuator] | None, single: Catalog
) -> list[MeasuredActuator]:
    pid, mid = single.propeller_ids[0], single.motor_ids[0]
    return [o for o in overrides or () if (o.propeller_id, o.motor_id) == (pid, mid)]


def design_record(grid: DesignGrid, i: int, j: int, k: int) -> dict[str, Any]:
    """The JSON keys of the issue for cell (i, j, k) of a grid, plus its checks."""
    record: dict[str, Any] = {
        "actuators": grid.n_actuators,
        "propeller": grid.propeller_ids[i],
        "motor": grid.motor_ids[j],
        "battery": grid.battery_ids[k],
        "payload_kg": grid.payload_kg,
    }
    for key in METRIC_KEYS:
        record[key] = float(grid.metrics[key][i, j, k])
    extras = getattr(grid, "extras", {})
    if "motor_current_a" in extras:
        record["motor_current_a"] = float(extras["motor_current_a"][i, j, k])
    checks = []
    violated = []
    for check in grid.checks:
        value = float(np.broadcast_to(check.value, grid.shape)[i, j, k])
        limit = float(np.broadcast_to(check.limit, grid.shape)[i, j, k])
        if math.isinf(limit):
            continue  # no limit for this design (e.g. no measured sweep of its actuator)
        margin = float(np.broadcast_to(check.margin(), grid.shape)[i, j, k])
        ok = bool(margin >= -1e-9 * max(1.0, abs(limit)))
        checks.append(
            {
                "label": check.label,
                "unit": check.unit,
                "value": value,
                "limit": limit,
                "sense": check.sense,
                "ok": ok,
            }
        )
        if not ok:
            unit = f" {check.unit}" if check.unit else ""
            op = ">" if check.sense == "<=" else "<"
            violated.append(f"{check.label} {value:.4g}{unit} {op} limit {limit:.4g}{unit}")
    record["feasible"] = not violated
    record["reason"] = "; ".join(violated)
    record["checks"] = checks
    measured = getattr(grid, "measured", {})
    record["measured"] = sorted(key for key, mask in measured.items() if mask[i, j, k])
    if isinstance(grid, ModelGrid) and grid.overrides:
        record["sources"] = design_sources(grid, i, j, k)
    return record


#: What the model uses where nothing is measured (equation numbers of Paper E).
MODEL_SOURCES: dict[str, str] = {
    "time_constant_ms": "model (E.35)",
    "current_a": "model (E.67-E.69)",
    "power_w": "model (E.60-E.63)",
    "flight_time_min": "model (E.67-E.74)",
}


def design_sources(grid: ModelGrid, i: int, j: int, k: int) -> dict[str, str]:
    """Which numbers of design (i, j, k) are measured (and in which run) or modelled.

    Keys: the metrics of ``MODEL_SOURCES`` and ``max_thrust`` (whether the measured top
    thrust was checked). A current outside the measured thrusts says so: the model's
    value is used there, never an extrapolation.
    """
    out = dict(MODEL_SOURCES)
    item = grid.overrides.get((i, j))
    if item is None:
        out["max_thrust"] = "not measured"
        return out
    tau_mask = grid.measured.get("time_constant_ms")
    if tau_mask is not None and tau_mask[i, j, k]:
        out["time_constant_ms"] = f"measured: run {item.run_of('time_constant')}"
    if not item.has_current:
        out["max_thrust"] = "not measured"
        return out
    run = item.run_of("current")
    cur_mask = grid.measured.get("current_a")
    if cur_mask is not None and cur_mask[i, j, k]:
        for key in ("current_a", "power_w", "flight_time_min"):
            out[key] = f"measured: run {run}"
    else:
        hover = float(grid.extras["hover_thrust_n"][i, j, k])
        lo, hi = float(item.hover_thrust_n[0]), float(item.hover_thrust_n[-1])
        where = "below" if hover < lo else "above"
        why = (
            f"; hover thrust {hover:.3g} N {where} the measured {lo:.3g}-{hi:.3g} N of run "
            f"{run} (not extrapolated)"
        )
        for key in ("current_a", "power_w", "flight_time_min"):
            out[key] += why
    top = item.top_thrust_n
    volt = float(grid.extras["voltage_v"][i, j, k])
    if top is not None and bool(item.top_thrust_applies(np.asarray([volt]))[0]):
        out["max_thrust"] = f"measured: run {run} ({top:.3g} N)"
    else:
        out["max_thrust"] = (
            f"not checked: battery {volt:.3g} V above the bench's {item.supply_voltage_v:.3g} V"
        )
    return out

