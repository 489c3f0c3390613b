"""Rules that make a design flyable, as a designer (and eCalc's warnings) would apply them.

The thesis' limits (motor power and current at hover, battery current) let through
designs nobody would build: on the SizingLab catalogs the longest flight is a 0.45 kg
quad with a 1804 motor of 1650 Kv on a 15 in propeller, 260 min, 2 s time constant. Each
rule below is one or two ``Check``s added to a grid (labels ``rule <name>: ...``), so the
MILP and enumeration treat them like any limit; each is switchable and reported with the
number of designs it removes.

* ``tip-speed``: propeller tip speed at full throttle <= ``tip_speed_m_s`` (default
  140 m/s, Mach 0.41; noise and efficiency fall apart well before the tip goes transonic,
  and an APC MR propeller's published limit of 105,000 rpm / D[in] is the same 140 m/s);
* ``frame``: motor-to-motor diagonal (2 x arm length, the thesis' geometry (D.4) from
  the propeller diameter) <= ``max_wheelbase_m`` (default 1.2 m, the size class of the
  largest camera octocopters): the propeller against the frame it needs;
* ``kv-prop``: the motor's winding current at full throttle <= its ``max_current_a``
  (eCalc's "motor overloaded at full throttle"): a Kv too high for the propeller;
* ``c-rate``: battery current at hover (with motor losses) <= continuous rating and at
  full throttle <= burst rating (``burst_c_rating``; the continuous one where absent);
* ``hover-throttle``: hover throttle within ``hover_throttle_pct`` (default 30-70 %):
  below, the controller has no resolution and the Kv is too high; above, there is no
  reserve to manoeuvre and the Kv is too low;
* ``response``: actuator time constant (E.35) <= ``max_time_constant_ms`` (default
  150 ms): attitude control needs thrust changes faster than the airframe's own
  dynamics (Paper D's case 1 objective; Table E.8's 4-actuator design has 123 ms).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from optimizer.catalogs.catalog import Catalog
from optimizer.errors import RequestError
from optimizer.model import operating_points as ops
from optimizer.model.grid import Check, DesignGrid, meets_checks

RULE_NAMES: tuple[str, ...] = (
    "tip-speed", "frame", "kv-prop", "c-rate", "hover-throttle", "response"
)


@dataclass(frozen=True)
class Rules:
    """Which rules apply and their limits (see the module doc)."""

    enabled: tuple[str, ...] = RULE_NAMES
    tip_speed_m_s: float = 140.0
    max_wheelbase_m: float = 1.2
    hover_throttle_pct: tuple[float, float] = (30.0, 70.0)
    max_time_constant_ms: float = 150.0

    def validate(self) -> Rules:
        unknown = [r for r in self.enabled if r not in RULE_NAMES]
        if unknown:
            raise RequestError(
                f"unknown rule {unknown[0]!r}; expected one of {', '.join(RULE_NAMES)}"
            )
        for name, value in (("tip speed", self.tip_speed_m_s),
                            ("max wheelbase", self.max_wheelbase_m),
                            ("max time constant", self.max_time_constant_ms)):
            if not math.isfinite(value) or value <= 0:
                raise RequestError(f"rule {name}: expected a number > 0, got {value:g}")
        lo, hi = self.hover_throttle_pct
        if not 0 <= lo < hi <= 100:
            raise RequestError(f"rule hover throttle: expected 0 <= low < high <= 100 %, "
                               f"got {lo:g}-{hi:g}")
        return self


def rule_of(check: Check) -> str | None:
    """The rule name of a check made here, None for any other check."""
    if check.label.startswith("rule "):
        return check.label[5:].split(":", 1)[0]
    return None


def rule_checks(
    catalog: Catalog,
    grid: DesignGrid,
    rules: Rules,
    coefficients: ops.Coefficients | None = None,
) -> tuple[Check, ...]:
    """The enabled rules as checks on ``grid`` (built from ``catalog``)."""
    from optimizer.model.sheet import drive_of, pack_of

    rules = rules.validate()
    n = grid.n_actuators
    drive = drive_of(catalog, coefficients)
    pack = pack_of(catalog)
    v_b = pack["voltage_v"]
    top = ops.at_throttle(drive, 1.0, v_b)
    out: list[Check] = []
    on = set(rules.enabled)
    if "tip-speed" in on:
        tip = np.pi * drive.diameter_m * top.rpm / 60.0
        out.append(Check("rule tip-speed: full-throttle tip speed", "m/s", tip,
                         np.asarray(rules.tip_speed_m_s)))
    if "frame" in on:
        wheelbase = 2.0 * grid.extras["arm_length_m"]  # type: ignore[attr-defined]
        out.append(Check("rule frame: motor-to-motor diagonal", "m", wheelbase,
                         np.asarray(rules.max_wheelbase_m)))
    if "kv-prop" in on:
        limit = catalog.motors["max_current_a"].to_numpy(float)[None, :, None]
        out.append(Check("rule kv-prop: full-throttle motor current", "A",
                         top.motor_current_a, limit))
    hover = None
    if "c-rate" in on or "hover-throttle" in on:
        hover = ops.at_thrust(drive, grid.extras["hover_thrust_n"], v_b)  # type: ignore
    if "c-rate" in on:
        assert hover is not None  # set just above for this rule
        out.append(Check("rule c-rate: hover battery current (continuous)", "A",
                         n * hover.battery_current_a, pack["continuous_a"]))
        out.append(Check("rule c-rate: full-throttle battery current (burst)", "A",
                         n * top.battery_current_a, pack["burst_a"]))
    if "hover-throttle" in on:
        assert hover is not None  # set just above for this rule
        pct = 100.0 * hover.throttle
        lo, hi = rules.hover_throttle_pct
        out.append(Check("rule hover-throttle: hover throttle (min)", "%", pct,
                         np.asarray(lo), ">="))
        out.append(Check("rule hover-throttle: hover throttle (max)", "%", pct, np.asarray(hi)))
    if "response" in on:
        out.append(Check("rule response: time constant", "ms", grid.metrics["time_constant_ms"],
                         np.asarray(rules.max_time_constant_ms)))
    return tuple(out)


@dataclass
class RuleReport:
    """How many designs of one grid each rule removes."""

    actuators: int
    designs: int
    physically_feasible: int
    #: rule -> designs (physically feasible) that fail this rule, whatever the others say
    removed_alone: dict[str, int]
    #: rule -> designs removed by this rule after the rules before it (in RULE_NAMES order)
    removed_in_turn: dict[str, int]
    flyable: int

    def to_dict(self) -> dict[str, Any]:
        return dict(self.__dict__)


def report(grid: DesignGrid, checks: Sequence[Check]) -> RuleReport:
    """Count what the rule checks in ``checks`` remove from ``grid``'s feasible designs."""
    def passes(cs: Sequence[Check]) -> np.ndarray:
        return meets_checks(grid, cs)  # the selection's own test, same tolerance

    base = passes([c for c in checks if rule_of(c) is None])
    names = list(dict.fromkeys(r for c in checks if (r := rule_of(c)) is not None))
    alone, in_turn = {}, {}
    alive = base.copy()
    for name in names:
        ok = passes([c for c in checks if rule_of(c) == name])
        alone[name] = int(np.count_nonzero(base & ~ok))
        in_turn[name] = int(np.count_nonzero(alive & ~ok))
        alive &= ok
    return RuleReport(grid.n_actuators, int(np.prod(grid.shape)), int(base.sum()), alone,
                      in_turn, int(alive.sum()))


@dataclass
class FlyableBuilder:
    """A ``build_grid`` for ``optimizer.solve.selection.optimize`` that adds the rule checks.

    ``reports`` collects one ``RuleReport`` per grid built.
    """

    rules: Rules
    base: Callable[[Catalog, int, float], DesignGrid] | None = None
    reports: list[RuleReport] = field(default_factory=list)
    #: measured C_t(rpm), C_p(rpm) for the full-throttle and hover rule values
    coefficients: ops.Coefficients | None = None

    def __call__(self, catalog: Catalog, n: int, payload: float) -> DesignGrid:
        if self.base is None:
            from optimizer.model.design_model import evaluate_grid

            grid = evaluate_grid(catalog, n, payload)
        else:
            grid = self.base(catalog, n, payload)
        checks = (*grid.checks, *rule_checks(catalog, grid, self.rules, self.coefficients))
        self.reports.append(report(grid, checks))
        return replace(grid, checks=checks)
