"""optimizer.solve.selection_options.solve: which options combine, and what each adds."""

from __future__ import annotations

import pytest

from optimizer.cases.paper_e_cases import PAPER_E_CASES
from optimizer.catalogs.catalog import load_catalog
from optimizer.errors import RequestError
from optimizer.model.flyable import Rules
from optimizer.solve.objectives import single
from optimizer.solve.selection import Requirements, optimize
from optimizer.solve.selection_options import solve
from tests.conftest import CATALOGS

CAT = load_catalog(CATALOGS / "thesis-e")


class _Measured:
    """A stand-in for a store's MeasuredSet: records what solve asks of it."""

    def __init__(self) -> None:
        self.built: list[int] = []
        self.annotated = 0

    def build_grid(self, catalog, n, payload_kg):
        from optimizer.model.design_model import evaluate_grid

        self.built.append(n)
        return evaluate_grid(catalog, n, payload_kg)

    def annotate(self, result) -> None:
        self.annotated += 1


def _picks(result):
    return [(d.propeller, d.motor, d.battery) for d in result.designs]


def test_plain_solve_is_optimize():
    req = Requirements(payload_kg=0.5)
    got = solve(CAT, single("flight-time"), (4, 6), req, "milp")
    assert _picks(got) == _picks(optimize(CAT, single("flight-time"), (4, 6), req, "milp"))
    assert not hasattr(got, "rule_reports")  # only the flyable rules add their reports


def test_measured_grids_are_built_and_annotated():
    m = _Measured()
    solve(CAT, single("time-constant"), (4, 8), Requirements(), "exact", m)
    assert m.built == [4, 8] and m.annotated == 1


def test_rules_report_what_they_removed():
    got = solve(CAT, single("flight-time"), (4,), Requirements(), "milp", rules=Rules())
    assert [r["actuators"] for r in got.rule_reports] == [4]


@pytest.mark.parametrize("kwargs, message", [
    ({"method": "thesis", "measured": _Measured()}, "--measured and --flyable work with"),
    ({"method": "thesis", "rules": Rules()}, "--measured and --flyable work with"),
    ({"method": "milp", "measured": _Measured(), "prop_data": {}}, "--prop-data works with"),
    ({"method": "thesis", "prop_data": {}}, "--prop-data works with"),
])
def test_combinations_that_do_not_work_are_refused(kwargs, message):
    method = kwargs.pop("method")
    with pytest.raises(RequestError, match=message):
        solve(CAT, single("flight-time"), (4,), Requirements(), method, **kwargs)


def test_paper_e_cases_are_the_three_tables():
    assert [(c, obj, p) for c, _, obj, p in PAPER_E_CASES] == [
        ("I", "flight-time", 0.0), ("II", "flight-time", 1.5), ("III", "time-constant", 0.0)]
    assert [t.split("(")[-1] for _, t, _, _ in PAPER_E_CASES] == [
        "Table E.8)", "Table E.9)", "Table E.10)"]


def test_packs_refuse_measured_and_add_rule_reports_per_count():
    from optimizer.solve.selection_options import solve_packs

    with pytest.raises(RequestError, match="--series/--parallel do not combine with --measured"):
        solve_packs(CAT, single("flight-time"), (4,), Requirements(), "milp", (3,), (1,),
                    _Measured())
    got = solve_packs(CAT, single("flight-time"), (4, 6), Requirements(), "milp", (2, 3),
                      (1, 2), rules=Rules())
    reports = got.rule_reports
    assert [r["actuators"] for r in reports] == [4, 6]  # one per count, not one per S
    grid_designs = len(CAT.propeller_ids) * len(CAT.motor_ids) * len(CAT.battery_ids) * 2 * 2
    assert all(r["designs"] == grid_designs for r in reports)


def test_roll_rise_option_refuses_the_thesis_method():
    from optimizer.solve.selection_options import meet_roll_rise_option

    with pytest.raises(RequestError, match="--max-roll-rise-ms works with --method milp"):
        meet_roll_rise_option(None, CAT, single("flight-time"), Requirements(), "thesis", 100.0)
