"""Section 2.4.1 of the thesis: choose the battery of an electric mobile robot by MILP.

The worked example that introduces the rules: four batteries (Table 2.2), current
proportional to the total weight (2.46), run time = capacity / current (2.56),
motor power ``E = R_a C^2`` limited to 30 W, with ``C^2`` approximated by ten equal
regions of the current axis (2.57)-(2.64). The state vector follows Tables 2.3-2.4
(30 variables: 4 battery Booleans, 10 region Booleans, W, P, C, R, C_1^2..C_10^2,
C^2, E).

Reading of (2.46): it prints ``C = (w_r + w_b) * 2 A/kg``, but the printed result
(battery #3, weight 5 kg, C = 5 A, 6 h, M = 6 A as "the highest current drain
possible") needs 1 A/kg; with 2 A/kg even the lightest robot draws 6 A = 36 W and
the problem is infeasible. The fixture ``optimizer/data/catalogs/thesis-robot`` carries
the constant ``current_per_kg_a = 1.0``; passing 2.0 reproduces the infeasibility.
"""

from __future__ import annotations

import csv
import tomllib
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from optimizer.errors import CatalogError
from optimizer.solve.milp_builder import Model, quicksum
from optimizer.solve.milp_rules import exactly_one, piecewise_linear


@dataclass(frozen=True)
class RobotProblem:
    """Table 2.2 plus the constants of section 2.4.1 (SI units)."""

    battery_ids: tuple[str, ...]
    capacity_ah: np.ndarray
    battery_mass_kg: np.ndarray
    battery_price: np.ndarray
    robot_mass_kg: float = 2.0
    current_per_kg_a: float = 1.0
    motor_resistance_ohm: float = 1.0
    power_limit_w: float | None = 30.0
    regions: int = 10
    eps: float = 1e-5

    def with_(self, **changes: object) -> RobotProblem:
        return replace(self, **changes)  # type: ignore[arg-type]


@dataclass(frozen=True)
class RobotResult:
    """The chosen battery and the MILP's values (``power_w`` is the linearised one)."""

    status: str
    battery: str | None
    weight_kg: float | None
    price: float | None
    current_a: float | None
    runtime_h: float | None
    power_w: float | None
    power_exact_w: float | None
    active_region: int | None
    n_vars: int
    n_binary: int
    n_constraints: int
    solve_time_s: float


_BATTERY_COLUMNS = ("id", "capacity_ah", "mass_kg", "price")
_CONSTANTS = {
    "robot_mass_kg": float,
    "current_per_kg_a": float,
    "motor_resistance_ohm": float,
    "power_limit_w": float,
    "regions": int,
    "eps": float,
}


def load_robot(folder: str | Path) -> RobotProblem:
    """Read ``batteries.csv`` and ``robot.toml`` of a robot folder (CatalogError if bad)."""
    folder = Path(folder)
    path = folder / "batteries.csv"
    try:
        with path.open(newline="", encoding="utf-8") as fh:
            rows = list(csv.DictReader(fh))
    except UnicodeDecodeError as exc:
        raise CatalogError(f"{path}: not UTF-8 text ({exc})") from None
    except OSError as exc:
        raise CatalogError(f"{path}: cannot read ({exc.strerror})") from None
    if not rows:
        raise CatalogError(f"{path}: no battery rows")
    missing = [c for c in _BATTERY_COLUMNS if c not in rows[0]]
    if missing:
        raise CatalogError(f"{path}: missing column(s) {', '.join(missing)}")
    ids: list[str] = []
    table = {c: [] for c in _BATTERY_COLUMNS[1:]}
    for n, row in enumerate(rows, start=2):
        bid = (row["id"] or "").strip()
        if not bid or bid in ids:
            raise CatalogError(f"{path}: row {n}, column id: empty or duplicate id {bid!r}")
        ids.append(bid)
        for col in table:
            try:
                val = float(row[col])
            except (TypeError, ValueError):
                raise CatalogError(
                    f"{path}: row {n}, column {col}: expected a number, got {row[col]!r}"
                ) from None
            if not np.isfinite(val) or val < 0 or (col != "price" and val == 0):
                raise CatalogError(f"{path}: row {n}, column {col}: expected > 0, got {val}")
            table[col].append(val)
    constants: dict[str, object] = {}
    toml_path = folder / "robot.toml"
    if toml_path.exists():
        try:
            raw = tomllib.loads(toml_path.read_text(encoding="utf-8"))
        except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:  # bytes that are not text
            raise CatalogError(f"{toml_path}: not valid TOML ({exc})") from None
        except OSError as exc:
            raise CatalogError(f"{toml_path}: cannot read ({exc.strerror})") from None
        for key, value in raw.items():
            if key not in _CONSTANTS:
                raise CatalogError(f"{toml_path}: unknown key {key!r}")
            try:
                constants[key] = _CONSTANTS[key](value)
            except (TypeError, ValueError):
                raise CatalogError(
                    f"{toml_path}: {key}: expected a number, got {value!r}"
                ) from None
            if constants[key] <= 0:  # type: ignore[operator]
                raise CatalogError(f"{toml_path}: {key}: expected > 0, got {value!r}")
    return RobotProblem(
        battery_ids=tuple(ids),
        capacity_ah=np.asarray(table["capacity_ah"]),
        battery_mass_kg=np.asarray(table["mass_kg"]),
        battery_price=np.asarray(table["price"]),
        **constants,  # type: ignore[arg-type]
    )


def build_robot_model(problem: RobotProblem) -> Model:
    """The MILP of section 2.4.1 (variable names follow Tables 2.3-2.4)."""
    p = problem
    current = (p.robot_mass_kg + p.battery_mass_kg) * p.current_per_kg_a  # (2.46), per battery
    runtime = p.capacity_ah / current  # (2.56), per battery
    c_max = float(current.max())  # "M = 6 A, the highest current drain possible"
    model = Model("robot-2.4.1")
    deltas = [model.binary(f"delta{i + 1}") for i in range(len(p.battery_ids))]  # x1..x4
    exactly_one(model, deltas, "one_battery")  # (2.51)
    # Region Booleans and C_n^2 are created by piecewise_linear below (x5..x14, x19..x28).
    w = model.continuous("W", 0.0, p.robot_mass_kg + float(p.battery_mass_kg.max()))  # x15
    price = model.continuous("P", 0.0, float(p.battery_price.max()))  # x16
    c = model.continuous("C", 0.0, c_max)  # x17
    r = model.continuous("R", 0.0, float(runtime.max()))  # x18
    model.add(
        w - quicksum(mk * d for mk, d in zip(p.battery_mass_kg, deltas, strict=True))
        == p.robot_mass_kg,
        name="weight",
    )  # (2.53)
    model.add(
        price == quicksum(pk * d for pk, d in zip(p.battery_price, deltas, strict=True)),
        name="price",
    )  # (2.54)
    model.add(
        c == quicksum(ck * d for ck, d in zip(current, deltas, strict=True)), name="current"
    )  # (2.46) as (2.54)
    model.add(
        r == quicksum(rk * d for rk, d in zip(runtime, deltas, strict=True)), name="runtime"
    )  # (2.56) as (2.54)
    pwl = piecewise_linear(
        model, c, np.square, 0.0, c_max, p.regions, "C2", spacing="x", eps=p.eps
    )  # (2.57)-(2.64)
    c2 = model.continuous("C^2", 0.0, c_max**2)  # x29
    model.add(c2 == pwl.y, name="C2_sum")
    e = model.continuous("E", 0.0, p.motor_resistance_ohm * c_max**2)  # x30
    model.add(e == p.motor_resistance_ohm * c2, name="power")  # (2.65)
    if p.power_limit_w is not None:
        model.add(e <= p.power_limit_w, name="power_limit")  # (2.66)
    model.maximize(r)  # (2.67): g = -1 at R
    return model


def solve_robot(problem: RobotProblem, time_limit: float = 10.0) -> RobotResult:
    """Build and solve the robot MILP; battery None when no battery meets the limit."""
    model = build_robot_model(problem)
    sol = model.solve(time_limit=time_limit)
    common: dict[str, Any] = dict(
        n_vars=model.n_vars,
        n_binary=model.count("binary"),
        n_constraints=model.n_constraints,
        solve_time_s=sol.solve_time_s,
    )
    if not sol.has_solution:
        return RobotResult(sol.status, None, None, None, None, None, None, None, None, **common)
    chosen = int(np.argmax([sol[f"delta{i + 1}"] for i in range(len(problem.battery_ids))]))
    region = int(np.argmax([sol[f"C2.d{i + 1}"] for i in range(problem.regions)])) + 1
    current = sol["C"]
    return RobotResult(
        status=sol.status,
        battery=problem.battery_ids[chosen],
        weight_kg=sol["W"],
        price=sol["P"],
        current_a=current,
        runtime_h=sol["R"],
        power_w=sol["E"],
        power_exact_w=problem.motor_resistance_ohm * current**2,
        active_region=region,
        **common,
    )
