"""Flyable-design rules (optimizer.model.flyable): values, switches, counts, exact selection."""

from __future__ import annotations

import numpy as np
import pytest

from bench.cli import main
from optimizer.catalogs.catalog import load_catalog
from optimizer.model.design_model import evaluate_design, evaluate_grid, single_design_catalog
from optimizer.model.flyable import RULE_NAMES, FlyableBuilder, Rules, rule_checks, rule_of
from optimizer.model.sheet import design_sheet
from optimizer.solve.objectives import single
from optimizer.solve.selection import optimize
from tests.conftest import CATALOGS, SIZINGLAB


@pytest.fixture
def thesis_e(fixtures_dir):
    return load_catalog(CATALOGS / "thesis-e")


def _value(checks, label: str, idx) -> float:
    check = next(c for c in checks if c.label.startswith(label))
    return float(np.broadcast_to(check.value, (4, 3, 4))[idx])


def test_grid_rules_equal_the_one_design_sheet(thesis_e) -> None:
    grid = evaluate_grid(thesis_e, 6)
    checks = rule_checks(thesis_e, grid, Rules())
    for idx in [(0, 0, 0), (3, 0, 2), (1, 2, 3), (2, 1, 1)]:
        ids = (thesis_e.propeller_ids[idx[0]], thesis_e.motor_ids[idx[1]],
               thesis_e.battery_ids[idx[2]])
        one = single_design_catalog(thesis_e, *ids)
        record = evaluate_design(thesis_e, 6, *ids)
        sheet = design_sheet(one, record)
        assert _value(checks, "rule hover-throttle: hover throttle (min)", idx) == pytest.approx(
            sheet["hover_throttle_pct"])
        assert _value(checks, "rule tip-speed", idx) == pytest.approx(sheet["tip_speed_max_m_s"])
        assert _value(checks, "rule kv-prop", idx) == pytest.approx(sheet["max_motor_current_a"])
        assert _value(checks, "rule c-rate: full-throttle", idx) == pytest.approx(
            sheet["max_battery_current_a"])


def test_each_rule_switches_off(thesis_e) -> None:
    grid = evaluate_grid(thesis_e, 4)
    for name in RULE_NAMES:
        rules = Rules(enabled=tuple(r for r in RULE_NAMES if r != name))
        names = {rule_of(c) for c in rule_checks(thesis_e, grid, rules)}
        assert name not in names and names == set(RULE_NAMES) - {name}


def test_counts_add_up_and_match_a_direct_count(thesis_e) -> None:
    builder = FlyableBuilder(Rules(hover_throttle_pct=(40.0, 70.0)))
    grid = builder(thesis_e, 4, 0.0)
    rep = builder.reports[0]
    assert rep.physically_feasible - sum(rep.removed_in_turn.values()) == rep.flyable
    assert rep.flyable == int(grid.feasible().sum())
    # direct: hover throttle of every design from the sheet, count those outside 40-70 %
    outside = 0
    for p in thesis_e.propeller_ids:
        for m in thesis_e.motor_ids:
            for b in thesis_e.battery_ids:
                rec = evaluate_design(thesis_e, 4, p, m, b)
                pct = design_sheet(single_design_catalog(thesis_e, p, m, b), rec)[
                    "hover_throttle_pct"]
                outside += rec["feasible"] and not 40.0 <= pct <= 70.0
    assert rep.removed_alone["hover-throttle"] == outside > 0


def test_milp_equals_enumeration_with_rules(thesis_e) -> None:
    for objective in ("flight-time", "time-constant", "price"):
        a = optimize(thesis_e, single(objective), (4, 6, 8), method="milp",
                     build_grid=FlyableBuilder(Rules()))
        b = optimize(thesis_e, single(objective), (4, 6, 8), method="exact",
                     build_grid=FlyableBuilder(Rules()))
        for da, db in zip(a.designs, b.designs, strict=True):
            assert (da.propeller, da.motor, da.battery) == (db.propeller, db.motor, db.battery)


def test_sizinglab_unflyable_best_is_removed(shared_data) -> None:
    from optimizer.catalogs.sizinglab import import_sizinglab

    cat = import_sizinglab(SIZINGLAB)
    plain = optimize(cat, single("flight-time"), (4,), method="milp").designs[0]
    ids = (plain.propeller, plain.motor, plain.battery)
    grid = evaluate_grid(cat, 4)
    checks = rule_checks(cat, grid, Rules())
    idx = (cat.propeller_ids.index(ids[0]), cat.motor_ids.index(ids[1]),
           cat.battery_ids.index(ids[2]))
    failed = {rule_of(c) for c in checks if np.broadcast_to(c.margin(), grid.shape)[idx] < 0}
    assert {"kv-prop", "response"} <= failed
    ruled = optimize(cat, single("flight-time"), (4,), method="milp",
                     build_grid=FlyableBuilder(Rules())).designs[0]
    exact = optimize(cat, single("flight-time"), (4,), method="exact",
                     build_grid=FlyableBuilder(Rules())).designs[0]
    assert (ruled.propeller, ruled.motor, ruled.battery) == (
        exact.propeller, exact.motor, exact.battery)
    assert ruled.metrics["flight_time_min"] < plain.metrics["flight_time_min"]
    assert ruled.metrics["time_constant_ms"] <= 150.0


def test_cli_flyable_and_errors(capsys) -> None:
    assert main(["optimize", "--flyable", "--actuators", "4"]) == 0
    out = capsys.readouterr().out
    assert "rules, 4 actuators" in out and "kv-prop" in out
    assert main(["optimize", "--no-rule", "frame"]) == 2
    assert "--no-rule has no effect without --flyable" in capsys.readouterr().err
    assert main(["optimize", "--flyable", "--hover-throttle", "80", "20"]) == 2
