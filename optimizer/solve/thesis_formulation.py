"""Paper E's own MILP (section 3, Tables E.1-E.4, eqs. E.12-E.74), built from the rules.

Why keep it: the default selector (``optimizer.solve.milp_exact``) is exact because it
precomputes every design; the thesis instead keeps the physics inside the MILP and
linearises the nonlinear parts (``n^3 = (n^2)^1.5`` and the squared arm distances)
with region Booleans. This module rebuilds that formulation so its answer, size,
solve time and linearisation error can be compared with the exact optimum.

Structure (one MILP per actuator count, as the thesis does):

* Booleans: one per propeller, motor, battery (E.13-E.15); one per region of the
  ``n^3`` approximation and of each squared distance (Table E.1).
* Continuous variables of Table E.3: ``x1..x21`` and the per-component sets
  ``x22..x96`` (n^2 per propeller, J_m, J_p, Ah, power, current, 1/flight time,
  one time constant per (propeller, motor, battery) by Rule 4), then the distances
  from the roll and pitch axes, their squares (PWL), the actuator and frame inertia
  sets (Rule 4 / Rule 1), the frame lengths and the PWL z-sets.
* Constants per component and per combination (masses, prices, arm lengths, battery
  voltage, ``J``, the time constants of E.32-E.39) come from ``optimizer.model.design_model``, so
  the two formulations share one physics.

Readings (see docs/thesis-formulation.md): (E.70)-(E.71) "x20 = x19" is used as
``x20 >= x19`` with ``T_F`` the required flight time (an equality would fix the
capacity); (E.55) is used with the ``1/3`` of (E.52) (a rod about its end); the
limits of ``optimizer.model.design_model`` (motor power and current, battery current) are added as
linear rows on x17 and x18; any other check is enforced per combination with
``d_p + d_m + d_b <= 2`` cuts (exact, no linearisation).
"""

from __future__ import annotations

import math
import time
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from optimizer.catalogs.catalog import Catalog
from optimizer.errors import RequestError
from optimizer.model import physics
from optimizer.model.design_model import (
    ModelGrid,
    design_record,
    evaluate_grid,
    motor_inertia_kgm2,
    propeller_inertia_kgm2,
)
from optimizer.model.grid import METRIC_KEYS, DesignGrid
from optimizer.solve.milp_builder import LinExpr, Model, Solution, Var, quicksum
from optimizer.solve.milp_rules import exactly_one, piecewise_linear, rule1_product, rule4_product

#: Objective name (CLI) -> (Table E.2 variable, sense).
OBJECTIVES: dict[str, tuple[str, str]] = {
    "flight-time": ("x21", "min"),  # min 1/flight time = max flight time
    "time-constant": ("x16", "min"),
    "power": ("x17", "min"),
    "price": ("x3", "min"),
    "roll-inertia": ("x13", "min"),
    "pitch-inertia": ("x14", "min"),
}

#: Region counts used by the thesis (Table E.4): 230 regions for n^3 (delta_12..delta_241)
#: and 160 per squared distance ((i2 - i1) / (N_a / 2) = 160 for N_a = 4, 6, 8).
THESIS_REGIONS: dict[str, int] = {"n3": 230, "distance": 160}

#: Largest catalog product the thesis formulation accepts (one Rule 4 term each).
MAX_COMBINATIONS = 5000

#: Thesis model sizes (section 3): total variables for N_a = 4, 6, 8.
THESIS_VARIABLE_COUNTS: dict[int, int] = {4: 1795, 6: 2444, 8: 3091}

#: Objective name -> (grid metric, sense) for the exact comparison (x17 is per propeller).
_EXACT_METRIC: dict[str, tuple[str, str]] = {
    "flight-time": ("flight_time_min", "max"),
    "time-constant": ("time_constant_ms", "min"),
    "power": ("propeller_power_w", "min"),
    "price": ("price", "min"),
    "roll-inertia": ("roll_inertia_kgm2", "min"),
    "pitch-inertia": ("pitch_inertia_kgm2", "min"),
}

#: Weighted sums (Paper D case 1) add terms in SI units: metric key, factor to SI.
_WEIGHTED_SI: dict[str, tuple[str, float]] = {
    "time-constant": ("time_constant_ms", 1e-3),
    "power": ("power_w", 1.0),
    "price": ("price", 1.0),
    "roll-inertia": ("roll_inertia_kgm2", 1.0),
    "pitch-inertia": ("pitch_inertia_kgm2", 1.0),
}

ObjectiveSpec = str | Mapping[str, float]


def _objective_terms(objective: ObjectiveSpec) -> tuple[tuple[str, float], ...]:
    """A single name, or a weighted sum {name: weight} of the linear objectives."""
    if isinstance(objective, str):
        if objective not in OBJECTIVES:
            raise RequestError(f"objective {objective!r}: expected one of {', '.join(OBJECTIVES)}")
        return ((objective, 1.0),)
    terms = []
    for name, weight in objective.items():
        if name not in _WEIGHTED_SI:
            raise RequestError(
                f"weighted objective: {name!r} cannot be weighted in the thesis formulation "
                f"(linear terms only: {', '.join(_WEIGHTED_SI)})"
            )
        if not math.isfinite(weight) or weight < 0:
            raise RequestError(f"weighted objective: weight of {name} must be >= 0, got {weight}")
        terms.append((name, float(weight)))
    if not terms or all(w == 0 for _, w in terms):
        raise RequestError("weighted objective: at least one weight must be > 0")
    return tuple(terms)


def _objective_name(terms: tuple[tuple[str, float], ...]) -> str:
    if len(terms) == 1 and terms[0][1] == 1.0 and terms[0][0] in OBJECTIVES:
        return terms[0][0]
    return "weighted(" + ",".join(f"{n}={w:g}" for n, w in terms) + ")"


def _objective_sense(terms: tuple[tuple[str, float], ...]) -> str:
    return _EXACT_METRIC[terms[0][0]][1] if len(terms) == 1 else "min"


def _exact_value(terms: tuple[tuple[str, float], ...], get: Any) -> Any:
    """Exact objective from metric values ``get(key)`` (arrays or floats)."""
    if len(terms) == 1 and terms[0][1] == 1.0:
        return get(_EXACT_METRIC[terms[0][0]][0])
    return sum(w * get(_WEIGHTED_SI[n][0]) * _WEIGHTED_SI[n][1] for n, w in terms)


@dataclass(frozen=True)
class ThesisResult:
    """One thesis-formulation MILP (one actuator count) and its check against the model.

    ``linearised`` holds the MILP's own values (x-variables converted to the metric
    units of ``optimizer.model.grid``); ``exact`` the model's values at the chosen design
    (``optimizer.model.design_model.design_record`` keys); ``errors`` their relative difference.
    """

    n_actuators: int
    objective: str
    status: str
    propeller: str | None
    motor: str | None
    battery: str | None
    index: tuple[int, int, int] | None
    objective_value: float | None
    linearised: dict[str, float]
    exact: dict[str, Any]
    n_vars: int
    n_binary: int
    n_continuous: int
    n_constraints: int
    solve_time_s: float
    build_time_s: float
    regions: dict[str, int]
    mip_gap: float | None = None
    message: str = ""
    errors: dict[str, float] = field(default_factory=dict)
    #: exact optimum of the objective over the same feasible set (brute force on the grid)
    exact_optimum: float | None = None
    #: ids (propeller, motor, battery) of every design reaching the exact optimum
    optimal_designs: tuple[tuple[str, str, str], ...] = ()
    #: the objective as (name, weight) terms
    terms: tuple[tuple[str, float], ...] = ()

    @property
    def exact_objective(self) -> float | None:
        """The exact model's objective at the thesis formulation's choice."""
        if not self.exact:
            return None
        return float(_exact_value(self.terms, lambda key: self.exact[key]))

    @property
    def linearised_objective(self) -> float | None:
        """The MILP's own (linearised) objective in the units of the exact one."""
        if not self.linearised:
            return None
        return float(_exact_value(self.terms, lambda key: self.linearised[key]))

    def design_entry(self) -> dict[str, Any]:
        """One ``designs`` entry of ``rotorbench optimize --json`` for this actuator count.

        Metrics are the exact model's values at the chosen design (what the build
        would do); the MILP's linearised values are under ``linearised``.
        """
        entry: dict[str, Any] = {"actuators": self.n_actuators, "feasible": self.feasible}
        if self.feasible:
            entry.update({k: v for k, v in self.exact.items() if k not in ("feasible", "reason")})
            entry["feasible"] = bool(self.exact.get("feasible", True))
        else:
            entry.update({"propeller": None, "motor": None, "battery": None})
            entry["reason"] = (
                f"thesis formulation: no design meets the requirements (HiGHS: {self.message})"
            )
        entry["solve_time_s"] = self.solve_time_s
        entry["method"] = "thesis"
        entry["linearised"] = dict(self.linearised)
        entry["linearised_objective"] = self.linearised_objective
        entry["model_size"] = {
            "variables": self.n_vars,
            "binary": self.n_binary,
            "constraints": self.n_constraints,
        }
        return entry

    @property
    def shortfall(self) -> float | None:
        """Relative loss of the choice against the exact optimum (0 when optimal, >= 0)."""
        if self.exact_objective is None or self.exact_optimum is None:
            return None
        sense = _objective_sense(self.terms)
        diff = self.exact_optimum - self.exact_objective
        loss = diff if sense == "max" else -diff
        return (loss / abs(self.exact_optimum) if self.exact_optimum else loss) + 0.0  # no -0.0

    @property
    def feasible(self) -> bool:
        return self.propeller is not None

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready summary (ids, counts, times, linearised and exact values)."""
        return {
            "actuators": self.n_actuators,
            "objective": self.objective,
            "status": self.status,
            "feasible": self.feasible,
            "propeller": self.propeller,
            "motor": self.motor,
            "battery": self.battery,
            "objective_value": self.objective_value,
            "linearised": self.linearised,
            "exact": {k: self.exact[k] for k in METRIC_KEYS if k in self.exact},
            "relative_error": self.errors,
            "n_vars": self.n_vars,
            "n_binary": self.n_binary,
            "n_continuous": self.n_continuous,
            "n_constraints": self.n_constraints,
            "solve_time_s": self.solve_time_s,
            "regions": self.regions,
            "linearised_objective": self.linearised_objective,
            "exact_objective": self.exact_objective,
            "exact_optimum": self.exact_optimum,
            "optimal_designs": [list(d) for d in self.optimal_designs],
            "shortfall": self.shortfall,
        }


def _regions(regions: int | Mapping[str, int]) -> dict[str, int]:
    if isinstance(regions, Mapping):
        out = {"n3": 10, "distance": 10, **{k: int(v) for k, v in regions.items()}}
        unknown = set(out) - {"n3", "distance"}
        if unknown:
            raise RequestError(f"regions: unknown key(s) {sorted(unknown)}; use n3, distance")
    else:
        out = {"n3": int(regions), "distance": int(regions)}
    if min(out.values()) < 1:
        raise RequestError(f"regions: expected whole numbers >= 1, got {out}")
    return out


@dataclass
class _Built:
    """The model and the handles needed to read a solution back."""

    model: Model
    x: dict[str, Var]
    d_prop: list[Var]
    d_motor: list[Var]
    d_batt: list[Var]
    grid: ModelGrid


def build_thesis_model(
    catalog: Catalog,
    n_actuators: int,
    objective: ObjectiveSpec,
    payload_kg: float = 0.0,
    min_flight_time_min: float | None = None,
    max_time_constant_ms: float | None = None,
    regions: int | Mapping[str, int] = 10,
) -> _Built:
    """Build (not solve) the Paper E MILP for one actuator count."""
    terms = _objective_terms(objective)
    reg = _regions(regions)
    combos = len(catalog.propellers) * len(catalog.motors) * len(catalog.batteries)
    if combos > MAX_COMBINATIONS:
        raise RequestError(
            f"thesis formulation: {combos} (propeller, motor, battery) combinations; it adds "
            f"one Rule 4 time constant per combination (E.35), so it is limited to "
            f"{MAX_COMBINATIONS}. Use the default method for large catalogs."
        )
    grid = evaluate_grid(catalog, n_actuators, payload_kg)
    na = grid.n_actuators
    c = catalog.constants
    rho, g = c.air_density_kg_m3, c.gravity_m_s2
    props, mots, bats = catalog.propellers, catalog.motors, catalog.batteries

    def col(frame: Any, name: str) -> np.ndarray:
        return frame[name].to_numpy(float)

    m_p, m_m, m_b = col(props, "mass_kg"), col(mots, "mass_kg"), col(bats, "mass_kg")
    diam, ct, cp = col(props, "diameter_m"), col(props, "ct"), col(props, "cp")
    price_p = col(props, "price") if c.price_includes_propellers else np.zeros(len(props))
    price_m, price_b = col(mots, "price"), col(bats, "price")
    ah_b = col(bats, "capacity_ah")
    volt_b = grid.extras["voltage_v"][0, 0, :]  # B_V (E.67), design_model's reading
    arm_p = grid.extras["arm_length_m"][:, 0, 0]  # L_f(D_i, N_a) (E.23)-(E.25)
    j_m, j_p = motor_inertia_kgm2(catalog), propeller_inertia_kgm2(catalog)
    tau_s = grid.metrics["time_constant_ms"] * 1e-3  # (E.32)-(E.39), per combination
    m_frame = c.frame_linear_density_kg_m  # m_F
    P, M, B = grid.shape

    model = Model(f"thesis-E-N{na}")
    x: dict[str, Var] = {}

    # Booleans (Table E.1) and (E.12)-(E.15).
    d_prop = [model.binary(f"d_prop[{pid}]") for pid in grid.propeller_ids]
    d_motor = [model.binary(f"d_motor[{mid}]") for mid in grid.motor_ids]
    d_batt = [model.binary(f"d_batt[{bid}]") for bid in grid.battery_ids]
    exactly_one(model, d_prop, "E.13:prop")
    exactly_one(model, d_motor, "E.14:motor")
    exactly_one(model, d_batt, "E.15:batt")

    def lin(coefs: np.ndarray, deltas: list[Var]) -> LinExpr:
        return quicksum(float(k) * d for k, d in zip(coefs, deltas, strict=True))

    def var(key: str, lo: float, hi: float) -> Var:
        x[key] = model.continuous(key, float(lo), float(hi))
        return x[key]

    # Weights and price (E.16)-(E.18).
    x2 = var("x2", na * (m_p.min() + m_m.min()), na * (m_p.max() + m_m.max()))
    model.add(x2 == na * (lin(m_p, d_prop) + lin(m_m, d_motor)), name="E.16")
    # Frame length and weight (E.23)-(E.26): x7 is the arm length L_f.
    lf = [var(f"Lf[{pid}]", 0, arm_p[i]) for i, pid in enumerate(grid.propeller_ids)]
    for i, v in enumerate(lf):
        model.add(v == float(arm_p[i]) * d_prop[i], name=f"E.23[{i}]")
    x7 = var("x7", arm_p.min(), arm_p.max())
    model.add(x7 == quicksum(lf), name="E.25")
    x8 = var("x8", m_frame * na * arm_p.min(), m_frame * na * arm_p.max())
    model.add(x8 == m_frame * na * x7, name="E.26")
    x1 = var("x1", x2.lb + x8.lb + m_b.min(), x2.ub + x8.ub + m_b.max())
    model.add(x1 == x2 + x8 + lin(m_b, d_batt), name="E.17")
    x3 = var("x3", 0, na * (price_p.max() + price_m.max()) + price_b.max())
    model.add(
        x3 == na * (lin(price_p, d_prop) + lin(price_m, d_motor)) + lin(price_b, d_batt),
        name="E.18",
    )

    # Thrust and n^2 per propeller (E.19)-(E.22).
    x4 = var("x4", (x1.lb + payload_kg) * g, (x1.ub + payload_kg) * g)
    model.add(x4 == (x1 + payload_kg) * g, name="E.19")
    k_n2 = 1.0 / (na * physics.thrust_n(ct, rho, 1.0, diam))  # (E.1): n^2 = F / (C_t rho D^4)
    n2_set = [
        rule1_product(model, d_prop[i], float(k_n2[i]) * x4, f"x22[{pid}]")
        for i, pid in enumerate(grid.propeller_ids)
    ]
    n2_max = float(np.max(k_n2) * x4.ub)
    x5 = var("x5", 0, n2_max)
    model.add(x5 == quicksum(n2_set), name="E.22")

    # Rotational inertias of motors and propellers (E.27)-(E.31) -> x15.
    jm_set = [var(f"x26[{mid}]", 0, j_m[j]) for j, mid in enumerate(grid.motor_ids)]
    jp_set = [var(f"x29[{pid}]", 0, j_p[i]) for i, pid in enumerate(grid.propeller_ids)]
    for j, v in enumerate(jm_set):
        model.add(v == float(j_m[j]) * d_motor[j], name=f"E.27[{j}]")
    for i, v in enumerate(jp_set):
        model.add(v == float(j_p[i]) * d_prop[i], name=f"E.30[{i}]")
    x15 = var("x15", 0, j_m.max() + j_p.max())
    model.add(x15 == quicksum(jm_set) + quicksum(jp_set), name="E.31")

    # Time constants (E.32)-(E.41): Rule 4 on (d_p, d_m, d_b) times a constant.
    tau_set = []
    for i in range(P):
        for j in range(M):
            for k in range(B):
                tau_set.append(
                    rule4_product(
                        model,
                        [d_prop[i], d_motor[j], d_batt[k]],
                        float(tau_s[i, j, k]),
                        f"x49[{i},{j},{k}]",
                    )
                )
    x16 = var("x16", 0, float(tau_s.max()))
    model.add(x16 == quicksum(tau_set), name="E.40")
    if max_time_constant_ms is not None:
        model.add(x16 <= max_time_constant_ms * 1e-3, name="E.41")

    # n^3 = (n^2)^1.5 by the nonlinear function approximation (E.60).
    n3 = piecewise_linear(
        model, x5, lambda v: np.asarray(v, float) ** 1.5, 0.0, n2_max, reg["n3"], "n3", spacing="y"
    )
    x6 = var("x6", 0, n2_max**1.5)
    model.add(x6 == n3.y, name="E.60")

    # Propeller power (E.61)-(E.63).
    k_pow = physics.propeller_power_w(cp, rho, 1.0, diam)  # (E.2): W = C_p rho D^5 n^3
    pow_set = [
        rule1_product(model, d_prop[i], float(k_pow[i]) * x6, f"x37[{pid}]")
        for i, pid in enumerate(grid.propeller_ids)
    ]
    x17 = var("x17", 0, float(k_pow.max()) * x6.ub)
    model.add(x17 == quicksum(pow_set), name="E.63")

    # Battery Ah (E.64)-(E.66).
    ah_set = [var(f"x33[{bid}]", 0, ah_b[k]) for k, bid in enumerate(grid.battery_ids)]
    for k, v in enumerate(ah_set):
        model.add(v == float(ah_b[k]) * d_batt[k], name=f"E.64[{k}]")
    x20 = var("x20", 0, ah_b.max())
    model.add(x20 == quicksum(ah_set), name="E.66")

    # Current (E.67)-(E.69).
    cur_set = [
        rule1_product(model, d_batt[k], na / float(volt_b[k]) * x17, f"x41[{bid}]")
        for k, bid in enumerate(grid.battery_ids)
    ]
    x18 = var("x18", 0, na / float(volt_b.min()) * x17.ub)
    model.add(x18 == quicksum(cur_set), name="E.69")

    # Required Ah (E.70)-(E.71), read as capacity >= required.
    if min_flight_time_min is not None:
        x19 = var("x19", 0, min_flight_time_min / 60.0 * x18.ub)
        model.add(x19 == (min_flight_time_min / 60.0) * x18, name="E.70")
        model.add(x20 >= x19, name="E.71")

    # 1 / flight time in 1/h (E.72)-(E.74).
    inv_set = [
        rule1_product(model, d_batt[k], x18 / float(ah_b[k]), f"x45[{bid}]")
        for k, bid in enumerate(grid.battery_ids)
    ]
    x21 = var("x21", 0, x18.ub / float(ah_b.min()))
    model.add(x21 == quicksum(inv_set), name="E.74")

    # Roll and pitch inertias (E.42)-(E.59): N_a/2 arm pairs, factor 2 per pair.
    half = na // 2 if na % 2 == 0 else na
    pair = 2.0 if na % 2 == 0 else 1.0
    angles = (2 * np.arange(half) + 1) * np.pi / na  # arms as in optimizer.model.physics
    axis_terms: dict[str, LinExpr] = {}
    for axis, factor in (("roll", np.abs(np.sin(angles))), ("pitch", np.abs(np.cos(angles)))):
        act_terms, frame_terms = [], []
        for k in range(half):
            dist = var(f"dist_{axis}[{k}]", factor[k] * arm_p.min(), factor[k] * arm_p.max())
            model.add(dist == float(factor[k]) * x7, name=f"dist_{axis}[{k}]")
            d_max = float(arm_p.max())  # every distance lies in [0, largest arm]
            sq = piecewise_linear(
                model, dist, np.square, 0.0, d_max, reg["distance"], f"d2_{axis}[{k}]", spacing="y"
            )
            d2 = var(f"dist2_{axis}[{k}]", 0, d_max**2)
            model.add(d2 == sq.y, name=f"E.42:{axis}[{k}]")
            for i in range(P):
                for j in range(M):  # (E.46)-(E.51): Rule 4 on (d_p, d_m)
                    act_terms.append(
                        rule4_product(
                            model,
                            [d_prop[i], d_motor[j]],
                            float(m_p[i] + m_m[j]) * d2,
                            f"act_{axis}[{k},{i},{j}]",
                        )
                    )
                # (E.52)-(E.57): Rule 1 on d_p, rod about its end: 1/3 L_f m_F d^2
                frame_terms.append(
                    rule1_product(
                        model,
                        d_prop[i],
                        float(arm_p[i] * m_frame / 3.0) * d2,
                        f"frame_{axis}[{k},{i}]",
                    )
                )
        axis_terms[f"act_{axis}"] = pair * quicksum(act_terms)
        axis_terms[f"frame_{axis}"] = pair * quicksum(frame_terms)
    for key, name, (lo, hi) in (
        ("x9", "act_roll", axis_terms["act_roll"].bounds()),
        ("x10", "act_pitch", axis_terms["act_pitch"].bounds()),
        ("x11", "frame_roll", axis_terms["frame_roll"].bounds()),
        ("x12", "frame_pitch", axis_terms["frame_pitch"].bounds()),
    ):
        v = var(key, lo, hi)
        model.add(v == axis_terms[name], name=f"E.48-57:{key}")
    x13 = var("x13", x["x9"].lb + x["x11"].lb, x["x9"].ub + x["x11"].ub)
    x14 = var("x14", x["x10"].lb + x["x12"].lb, x["x10"].ub + x["x12"].ub)
    model.add(x13 == x["x9"] + x["x11"], name="E.58")
    model.add(x14 == x["x10"] + x["x12"], name="E.59")

    # Limits of optimizer.model.design_model as linear rows; other checks as per-combination cuts.
    limits = {
        "motor power": lambda: x17 <= lin(col(mots, "max_power_w"), d_motor),
        "motor current": lambda: x18 / na <= lin(col(mots, "max_current_a"), d_motor),
        "battery current": lambda: x18 <= lin(col(bats, "max_current_a"), d_batt),
    }
    for check in grid.checks:
        if check.label in limits:
            model.add(limits[check.label](), name=f"limit:{check.label}")
            continue
        ok = np.broadcast_to(check.margin() >= 0, grid.shape)
        for i, j, k in zip(*np.nonzero(~ok), strict=True):
            model.add(d_prop[i] + d_motor[j] + d_batt[k] <= 2, name=f"cut:{check.label}")

    if len(terms) == 1 and terms[0][1] == 1.0:
        key, sense = OBJECTIVES[terms[0][0]]  # Table E.2
        (model.minimize if sense == "min" else model.maximize)(x[key])
    else:  # weighted sum in SI units (Paper D case 1: x16 + x13 + x14)
        si = {
            "time-constant": x16,
            "power": na * x17,
            "price": x3,
            "roll-inertia": x13,
            "pitch-inertia": x14,
        }
        model.minimize(quicksum(w * si[name] for name, w in terms))
    return _Built(model, x, d_prop, d_motor, d_batt, grid)


def _linearised_values(sol: Solution, payload_kg: float, na: int) -> dict[str, float]:
    """The MILP's x-variables in the units of ``optimizer.model.grid`` metrics."""
    x21 = sol["x21"]
    return {
        "flight_time_min": 60.0 / x21 if x21 > 0 else math.inf,
        "time_constant_ms": sol["x16"] * 1e3,
        "price": sol["x3"],
        "total_mass_kg": sol["x1"] + payload_kg,
        "hover_rpm": 60.0 * math.sqrt(max(sol["x5"], 0.0)),
        "propeller_power_w": sol["x17"],
        "power_w": na * sol["x17"],
        "current_a": sol["x18"],
        "roll_inertia_kgm2": sol["x13"],
        "pitch_inertia_kgm2": sol["x14"],
    }


def exact_optimum(
    grid: DesignGrid,
    objective: ObjectiveSpec,
    min_flight_time_min: float | None = None,
    max_time_constant_ms: float | None = None,
    rel_tol: float = 1e-9,
) -> tuple[float | None, tuple[tuple[str, str, str], ...]]:
    """Brute-force optimum of ``objective`` on a grid and every design that reaches it."""
    terms = _objective_terms(objective)
    sense = _objective_sense(terms)
    ok = grid.feasible()
    if min_flight_time_min is not None:
        ok &= grid.metrics["flight_time_min"] >= min_flight_time_min
    if max_time_constant_ms is not None:
        ok &= grid.metrics["time_constant_ms"] <= max_time_constant_ms
    value = np.asarray(_exact_value(terms, lambda key: grid.metrics[key]), float)
    ok &= np.isfinite(value)
    if not ok.any():
        return None, ()
    best = float(value[ok].max() if sense == "max" else value[ok].min())
    hit = ok & (np.abs(value - best) <= rel_tol * max(abs(best), 1e-300))
    designs = tuple(
        (grid.propeller_ids[i], grid.motor_ids[j], grid.battery_ids[k])
        for i, j, k in zip(*np.nonzero(hit), strict=True)
    )
    return best, designs


def solve_thesis(
    catalog: Catalog,
    n_actuators: int,
    objective: ObjectiveSpec,
    payload_kg: float = 0.0,
    min_flight_time_min: float | None = None,
    max_time_constant_ms: float | None = None,
    regions: int | Mapping[str, int] = 10,
    time_limit: float = 60.0,
) -> ThesisResult:
    """Build and solve the Paper E MILP for one actuator count; compare with the model.

    ``objective`` is a Table E.2 name (``flight-time``, ``time-constant``, ``power``,
    ``price``, ``roll-inertia``, ``pitch-inertia``) or a weighted sum ``{name: weight}``
    of the linear ones in SI units (Paper D case 1: time-constant + roll + pitch).
    """
    terms = _objective_terms(objective)
    t0 = time.perf_counter()
    built = build_thesis_model(
        catalog,
        n_actuators,
        objective,
        payload_kg,
        min_flight_time_min,
        max_time_constant_ms,
        regions,
    )
    build_time = time.perf_counter() - t0
    model, grid = built.model, built.grid
    sol = model.solve(time_limit=time_limit)
    common: dict[str, Any] = dict(
        n_actuators=grid.n_actuators,
        objective=_objective_name(terms),
        terms=terms,
        status=sol.status,
        n_vars=model.n_vars,
        n_binary=model.count("binary"),
        n_continuous=model.count("continuous"),
        n_constraints=model.n_constraints,
        solve_time_s=sol.solve_time_s,
        build_time_s=build_time,
        regions=_regions(regions),
        mip_gap=sol.mip_gap,
        message=sol.message,
    )
    best, designs = exact_optimum(grid, objective, min_flight_time_min, max_time_constant_ms)
    common["exact_optimum"] = best
    common["optimal_designs"] = designs
    if not sol.has_solution:
        return ThesisResult(
            propeller=None,
            motor=None,
            battery=None,
            index=None,
            objective_value=None,
            linearised={},
            exact={},
            **common,
        )
    i = int(np.argmax([sol.value(d) for d in built.d_prop]))
    j = int(np.argmax([sol.value(d) for d in built.d_motor]))
    k = int(np.argmax([sol.value(d) for d in built.d_batt]))
    exact = design_record(grid, i, j, k)
    lin_vals = _linearised_values(sol, grid.payload_kg, grid.n_actuators)
    errors = {}
    for key, val in lin_vals.items():
        ref = exact[key]
        errors[key] = (val - ref) / ref if ref else (0.0 if val == ref else math.inf)
    return ThesisResult(
        propeller=grid.propeller_ids[i],
        motor=grid.motor_ids[j],
        battery=grid.battery_ids[k],
        index=(i, j, k),
        objective_value=sol.objective,
        linearised=lin_vals,
        exact=exact,
        errors=errors,
        **common,
    )
