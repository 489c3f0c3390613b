"""The pure sweep engine (optimizer.sweep): which designs, their ids, the rows, errors."""

from __future__ import annotations

import json

import pytest

from bench.cli import main
from bench.store.catalogs import with_min_thrust_to_weight
from optimizer.catalogs.catalog import load_catalog
from optimizer.flight.maneuvers import MANEUVERS, fly
from optimizer.flight.ranking import roll_step, spearman
from optimizer.model.design_model import evaluate_grid
from optimizer.model.flyable import FlyableBuilder, Rules
from optimizer.solve.packs import cells_of, packs_at
from optimizer.sweep.chunks import DEFAULT_CHUNK_SIZE, MIN_CHUNK_SIZE, chunk_size, split
from optimizer.sweep.designs import Packs, grid_designs, plan_designs, thrust_to_weight
from optimizer.sweep.flight_params import flight_of
from optimizer.sweep.fly_rows import Chunk, fly_chunk
from optimizer.sweep.keys import design_id
from optimizer.sweep.ranking import rank
from optimizer.sweep.rows import columns, figure_names
from optimizer.sweep.spec import spec_difference
from tests.conftest import CATALOGS


def test_design_id_is_a_stable_hash_of_the_keys() -> None:
    """The id names the design in every run (resume): its value is fixed here."""
    assert design_id(4, "P1", "M1", "B1", 3, 1) == "33c6b4727ca5bc2b"
    others = {design_id(4, "P1", "M1", "B1", 3, 2), design_id(6, "P1", "M1", "B1", 3, 1),
              design_id(4, "P1", "M1", "B2", 3, 1), design_id(4, "P1", "M1", "B1", 4, 1)}
    assert len(others) == 4 and "33c6b4727ca5bc2b" not in others


def test_the_plan_is_every_design_optimize_considers(thesis_e) -> None:
    plan = plan_designs(thesis_e, [4, 6])
    for n in (4, 6):
        grid = evaluate_grid(thesis_e, n)
        ours = plan[plan["actuators"] == n]
        assert len(ours) == int(grid.feasible().sum())
        assert (ours["time_constant_ms"].to_numpy() ==
                grid.metrics["time_constant_ms"][grid.feasible()]).all()  # catalog order
    assert len(plan[plan["actuators"] == 4]) == 44
    assert set(plan["series"]) == {3} and set(plan["parallel"]) == {1}  # 3S batteries
    assert plan["design_id"].is_unique
    assert (plan.filter(like="std_").to_numpy() == 0).all()  # the model's: no spread
    flyable = plan_designs(thesis_e, [4], build_grid=FlyableBuilder(Rules()))
    assert 0 < len(flyable) == int(FlyableBuilder(Rules())(thesis_e, 4, 0.0).feasible().sum())


def test_pack_designs_are_keyed_by_cell_series_and_parallel(thesis_e) -> None:
    plan = plan_designs(thesis_e, [4], packs=Packs((3, 4), (1, 2)))
    cells = cells_of(thesis_e)
    expected = sum(int(evaluate_grid(packs_at(thesis_e, cells, s, (1, 2)), 4).feasible().sum())
                   for s in (3, 4))
    assert len(plan) == expected > 0
    assert set(plan["battery"]) <= set(cells["id"])
    assert set(plan["series"]) == {3, 4} and set(plan["parallel"]) == {1, 2}
    assert list(plan["series"]) == sorted(plan["series"])  # one series count after another


def _pick(catalog, propeller, motor, battery):
    plan = plan_designs(catalog, [4])
    return plan[(plan["propeller"] == propeller) & (plan["motor"] == motor) &
                (plan["battery"] == battery)]


#: one design under the margin, and the thesis' pick that cannot hover (--thesis-rules)
FLOWN = [(("P1", "M1", "B1"), []), (("P1", "M1", "B3"), ["--thesis-rules"])]


@pytest.fixture(scope="module")
def flown_rows(thesis_e):
    """The sweep engine's rows of the :data:`FLOWN` designs, by design: both in one chunk,
    as a sweep flies them (a design's numbers do not depend on its chunk), so each
    maneuver is one batch flight instead of one per design."""
    import pandas as pd

    plain = load_catalog(CATALOGS / "thesis-e")
    picks = [_pick(plain if rules else thesis_e, *design) for design, rules in FLOWN]
    assert [len(p) for p in picks] == [1, 1]
    rows = fly_chunk(Chunk(pd.concat(picks, ignore_index=True), ("roll_step", "gust")))
    return {design: row for (design, _), row in zip(FLOWN, rows, strict=True)}


@pytest.mark.parametrize("design, rules", FLOWN)
def test_rows_hold_the_numbers_rotorbench_fly_prints(capsys, flown_rows, design,
                                                     rules) -> None:
    """The same figures, exactly: one design under the margin, and the thesis' pick that
    cannot hover (flown under --thesis-rules, its note kept)."""
    argv = ["fly", "--actuators", "4", "--propeller", design[0], "--motor", design[1],
            "--battery", design[2], "--maneuver", "roll_step", "gust", "--json", *rules]
    assert main(argv) == 0
    doc = json.loads(capsys.readouterr().out)
    row = flown_rows[design]
    for m in ("roll_step", "gust"):
        assert {f: row[f"{m}_{f}"] for f in figure_names(m)} == doc["maneuvers"][m]
    assert row["time_constant_ms"] == doc["design"]["time_constant_ms"]
    assert row["tau_up_ms"] == doc["actuator"]["tau_up_ms"]
    assert row["can_hover"] is doc["hover"]["can_hover"]
    assert (row["note"] or "") == doc["hover"]["note"]
    assert row["error"] is None


def test_figure_columns_name_every_figure_a_maneuver_has(thesis_e) -> None:
    plan = plan_designs(thesis_e, [4]).head(1)
    vehicle, actuator = flight_of(plan.to_dict("records")[0])
    for name, man in MANEUVERS.items():
        short = type(man)(man.name, man.axis, man.amplitude, 0.3)  # the keys, not the values
        assert set(fly(vehicle, actuator, short, record=False).figures) == \
            set(figure_names(name)), name
    names = [c for c, _ in columns(list(MANEUVERS))]
    assert len(names) == len(set(names))


def test_a_design_that_fails_is_a_row_with_its_error(thesis_e) -> None:
    """A broken actuator (tau 0) and a design the flight model refused when planned: rows
    with the error; the design between them flies."""
    plan = plan_designs(thesis_e, [4]).head(3).copy()
    plan.loc[0, "actuator_tau_up_s"] = 0.0
    plan.loc[2, "setup_error"] = "RequestError: vehicle 4x P1+M2+B1: k_f must be > 0"
    rows = fly_chunk(Chunk(plan, ("roll_step",)))
    assert [r["design_id"] for r in rows] == list(plan["design_id"])
    assert rows[0]["error"].startswith("RequestError: actuator (model (E.35)): tau_up_s "
                                       "must be > 0 s")
    assert rows[0]["roll_step_rise_time_ms"] is None
    assert rows[1]["error"] is None and rows[1]["roll_step_rise_time_ms"] > 0
    assert rows[2]["error"] == "RequestError: vehicle 4x P1+M2+B1: k_f must be > 0"
    assert rows[2]["flight_time_min"] == plan.loc[2, "flight_time_min"]  # static numbers kept


def test_a_design_the_flight_model_refuses_is_planned_with_why(thesis_e) -> None:
    """setup() raising for one design (a negative drag here: any design) is recorded in
    the plan, not raised: the sweep goes on and writes the reason."""
    grid = evaluate_grid(thesis_e, 4)
    plan = grid_designs(thesis_e, grid, layout="hexagon")
    assert len(plan) == 44
    assert plan["setup_error"].str.startswith("RequestError: layout: expected one of").all()
    [row] = fly_chunk(Chunk(plan.head(1), ("roll_step",)))
    assert row["error"].startswith("RequestError: layout") and row["can_hover"] is None


def test_thrust_to_weight_without_the_margin_is_the_margin_grids(thesis_e) -> None:
    """Under --thesis-rules the grid has no ratio; the sweep computes it with the same
    formula, so both are one number."""
    plain = load_catalog(CATALOGS / "thesis-e")
    assert plain.constants.min_thrust_to_weight is None
    bare = evaluate_grid(plain, 4)
    assert "thrust_to_weight" not in bare.extras
    margin = evaluate_grid(with_min_thrust_to_weight(plain, 1.2), 4)
    assert thrust_to_weight(plain, bare) == pytest.approx(margin.extras["thrust_to_weight"],
                                                          rel=1e-12)


def test_chunk_sizes() -> None:
    assert chunk_size(44, 2) == chunk_size(3, 8) == MIN_CHUNK_SIZE  # one chunk: all of it
    assert chunk_size(20_000, 8) == 625  # four per worker
    assert chunk_size(10**6, 64) == DEFAULT_CHUNK_SIZE
    assert chunk_size(44, 2, given=100) == 100
    import pandas as pd

    chunks = split(pd.DataFrame({"design_id": list("abcdefg")}), ["roll_step"], 3)
    assert [list(c.designs["design_id"]) for c in chunks] == [list("abc"), list("def"), ["g"]]


def test_spec_difference_names_the_first_key() -> None:
    a = {"catalog": "x", "maneuvers": ["roll_step"], "rules": None}
    assert spec_difference(a, dict(a)) is None
    assert spec_difference(a, {**a, "maneuvers": ("roll_step",)}) is None  # JSON alike
    assert spec_difference(a, {**a, "maneuvers": ["gust"]}) == \
        'maneuvers: ["roll_step"] there, ["gust"] now'
    nested = {"options": {"rules": {"tip_speed_m_s": 140.0}, "layout": "x"}}
    other = {"options": {"rules": {"tip_speed_m_s": 120.0}, "layout": "x"}}
    assert spec_difference(nested, other) == "options.rules.tip_speed_m_s: 140.0 there, " \
        "120.0 now"
    assert spec_difference(nested, {"options": {**nested["options"], "rules": None}}) == \
        'options.rules: {"tip_speed_m_s": 140.0} there, null now'


def test_rank_flies_what_one_design_flies(thesis_e) -> None:
    """The ranking from the sweep engine's rows equals flying each design alone
    (``optimizer.flight.ranking.roll_step``, what optimize --max-roll-rise-ms flies), on
    the P1 and P2 designs with M1 (the progress callback sees each batch flight)."""
    from optimizer.catalogs.catalog import Catalog

    small = Catalog(thesis_e.propellers.iloc[:2], thesis_e.motors.iloc[:1],
                    thesis_e.batteries, thesis_e.constants, thesis_e.source)
    grid = evaluate_grid(small, 4)
    seen: list[tuple[int, int]] = []
    ranking = rank(small, grid, lambda i, total: seen.append((i, total)))
    assert len(ranking.rows) == int(grid.feasible().sum()) >= 3
    assert seen == [(len(ranking.rows), len(ranking.rows))]  # one batch of RANK_CHUNK
    for r in ranking.rows:
        index = (grid.propeller_ids.index(r.propeller), grid.motor_ids.index(r.motor),
                 grid.battery_ids.index(r.battery))
        assert roll_step(small, grid, index) == r
    assert ranking.rho == spearman(ranking.rows)[0]


@pytest.mark.parametrize("layout, drag, packs", [("x", 0.0, False), ("plus", 0.3, False),
                                                 ("x", 0.0, True)])
def test_the_plans_model_numbers_are_setups(thesis_e, layout, drag, packs) -> None:
    """The plan's vectorised model numbers (``optimizer.sweep.model_params``) are exactly
    ``params_of(*setup(...))`` of each design, for every actuator count."""
    import numpy as np

    from optimizer.flight.design import feasible_indices, setup
    from optimizer.sweep.flight_params import param_columns, params_of
    from optimizer.sweep.model_params import model_params, modelled

    catalog = packs_at(thesis_e, cells_of(thesis_e), 4, (1, 2)) if packs else thesis_e
    for n in (4, 6, 8):
        grid = evaluate_grid(catalog, n)
        idx = np.array(feasible_indices(grid)).reshape(-1, 3)
        assert len(idx) > 10 and modelled(grid, idx).all()
        frame = model_params(catalog, grid, idx, layout, drag)
        assert frame.pop("valid").all()
        for row, index in zip(frame.to_dict("records"), map(tuple, idx.tolist()),
                              strict=True):
            want = params_of(*setup(catalog, grid, index, layout=layout, drag_n_s_m=drag))
            assert [row[c] for c in param_columns()] == [want[c] for c in param_columns()]
