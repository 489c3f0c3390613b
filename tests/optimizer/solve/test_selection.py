"""Selection on synthetic grids: objectives, ties, requirements, infeasibility."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from optimizer.errors import RequestError
from optimizer.model.grid import METRIC_KEYS, Check, DesignGrid
from optimizer.solve.objectives import parse_weights, single, weighted
from optimizer.solve.selection import (
    TIE_ORDER,
    Requirements,
    break_ties,
    select_from_grids,
    tied_set,
)


def make_grid(n: int = 4, shape=(2, 2, 2), checks=(), **metrics: np.ndarray) -> DesignGrid:
    base = {key: np.full(shape, 1.0) for key in METRIC_KEYS}
    base.update({k: np.asarray(v, float).reshape(shape) for k, v in metrics.items()})
    p, m, b = shape
    return DesignGrid(
        n_actuators=n,
        payload_kg=0.0,
        propeller_ids=tuple(f"P{i + 1}" for i in range(p)),
        motor_ids=tuple(f"M{i + 1}" for i in range(m)),
        battery_ids=tuple(f"B{i + 1}" for i in range(b)),
        metrics=base,
        checks=tuple(checks),
    )


@pytest.mark.parametrize("method", ["milp", "exact"])
def test_max_and_min_objectives(method: str) -> None:
    ft = np.arange(8.0)
    grid = make_grid(flight_time_min=ft, price=8 - ft)
    res = select_from_grids([grid], single("flight-time"), method=method)
    assert res.designs[0].index == (1, 1, 1)
    res = select_from_grids([grid], single("price"), method=method)
    assert res.designs[0].index == (1, 1, 1)  # price 1 is the lowest
    res = select_from_grids([grid], single("time-constant"), method=method)
    assert res.designs[0].n_tied == 8  # all equal: tie-break by flight time
    assert res.designs[0].index == (1, 1, 1)


@pytest.mark.parametrize("method", ["milp", "exact"])
def test_tie_goes_to_faster_actuators_and_dominated_twin_loses(method: str) -> None:
    # same flight time and price for four designs; design 5 has the fastest actuators
    ft = np.array([10, 10, 30, 10, 30, 30, 5, 30.0])
    price = np.array([1, 1, 2, 1, 2, 2, 1, 2.0])
    tau = np.array([50, 50, 90, 50, 40, 40, 50, 60.0])
    power = np.array([1, 1, 1, 1, 3, 2, 1, 1.0])  # design 5 dominates its twin 4 (power)
    grid = make_grid(flight_time_min=ft, price=price, time_constant_ms=tau, power_w=power)
    res = select_from_grids([grid], single("flight-time"), method=method)
    d = res.designs[0]
    assert d.n_tied == 4
    assert np.ravel_multi_index(d.index, grid.shape) == 5
    assert (d.propeller, d.motor, d.battery) == ("P2", "M1", "B2")


def test_tie_tolerance_and_position_fallback() -> None:
    ft = np.array([10, 10 * (1 + 1e-8), 9, 10 * (1 - 1e-3), 1, 1, 1, 1.0])
    grid = make_grid(flight_time_min=ft)
    cost = single("flight-time").cost(grid)
    tied = tied_set(cost, np.ones(grid.shape, bool), float(cost.ravel()[1]))
    assert tied.tolist() == [0, 1]  # within 1e-6 relative; 1e-3 apart is not a tie
    # everything else equal: the first in catalog order wins
    assert break_ties(grid, tied, single("flight-time")) == 0


def test_solver_answer_slightly_off_is_refined_to_the_same_set() -> None:
    ft = np.array([10, 10 - 1e-7, 3, 3, 3, 3, 3, 3.0])
    grid = make_grid(flight_time_min=ft)
    cost = single("flight-time").cost(grid)
    ok = np.ones(grid.shape, bool)
    assert tied_set(cost, ok, cost.ravel()[1]).tolist() == tied_set(cost, ok, -10).tolist()


@pytest.mark.parametrize("method", ["milp", "exact"])
def test_requirements_and_limit_checks(method: str) -> None:
    ft = np.arange(8.0)
    tau = np.array([10, 20, 30, 40, 50, 60, 70, 80.0])
    current = np.array([1, 1, 1, 1, 1, 1, 1, 99.0])
    checks = [Check("battery current", "A", current.reshape(2, 2, 2), np.asarray(50.0))]
    grid = make_grid(flight_time_min=ft, time_constant_ms=tau, checks=checks)
    res = select_from_grids([grid], single("flight-time"), method=method)
    assert np.ravel_multi_index(res.designs[0].index, grid.shape) == 6  # 7 violates current
    req = Requirements(max_time_constant_ms=45)
    res = select_from_grids([grid], single("flight-time"), req, method=method)
    assert np.ravel_multi_index(res.designs[0].index, grid.shape) == 3
    req = Requirements(min_flight_time_min=2.5)
    res = select_from_grids([grid], single("time-constant"), req, method=method)
    assert np.ravel_multi_index(res.designs[0].index, grid.shape) == 3


def test_infeasible_explains_closest_design_and_amount() -> None:
    ft = np.array([10, 20, 30, 40, 50, 60, 70, 80.0])
    current = np.array([1, 1, 1, 1, 1, 1, 1, 99.0])
    checks = [Check("battery current", "A", current.reshape(2, 2, 2), np.asarray(50.0))]
    grid = make_grid(flight_time_min=ft, checks=checks)
    req = Requirements(min_flight_time_min=75)
    res = select_from_grids([grid], single("price"), req, method="milp")
    d = res.designs[0]
    assert not d.feasible and res.best is None
    # closest: design 6 misses 75 min by 5 min (6.7 %); design 7 meets it but draws 99 A (98 %)
    assert d.closest["propeller"] == "P2" and d.closest["battery"] == "B1"
    assert "short by 5 min" in d.reason and "6.7 %" in d.reason
    assert "no design meets flight time" not in d.reason  # design 7 reaches 80 min
    entry = d.to_dict()
    assert entry["feasible"] is False and entry["propeller"] is None and "reason" in entry
    req = Requirements(min_flight_time_min=100)
    d = select_from_grids([grid], single("price"), req).designs[0]
    assert "no design meets flight time (required minimum) (limit 100 min; best 80 min)" in (
        d.reason
    )


def test_best_across_actuator_counts_and_tie_prefers_fewer() -> None:
    g4 = make_grid(4, flight_time_min=np.full(8, 20.0), price=np.full(8, 5.0))
    g6 = make_grid(6, flight_time_min=np.full(8, 20.0), price=np.full(8, 4.0))
    g8 = make_grid(8, flight_time_min=np.full(8, 20.0), price=np.full(8, 5.0))
    res = select_from_grids([g4, g6, g8], single("flight-time"))
    assert res.best.actuators == 6  # equal flight time, cheaper
    g6b = make_grid(6, flight_time_min=np.full(8, 20.0), price=np.full(8, 5.0))
    res = select_from_grids([g8, g6b, g4], single("flight-time"))
    assert res.best.actuators == 4
    res = select_from_grids(
        [g4, make_grid(6, flight_time_min=np.full(8, 21.0))], single("flight-time")
    )
    assert res.best.actuators == 6


def test_weighted_range_normalisation_shared_across_counts() -> None:
    ft = np.array([10, 20, 30, 40, 0, 0, 0, 0.0])
    price = np.array([1, 2, 3, 10, 0, 0, 0, 0.0])
    checks = [
        Check("x", "", np.array([0, 0, 0, 0, 1, 1, 1, 1.0]).reshape(2, 2, 2), np.asarray(0.5))
    ]
    grid = make_grid(flight_time_min=ft, price=price, checks=checks)
    # ranges over feasible designs: ft 10..40, price 1..10
    obj = weighted({"flight-time": 1, "price": 1})
    res = select_from_grids([grid], obj, method="exact")
    # costs: (40-ft)/30 + (p-1)/9 -> 1.0, 0.778, 0.556, 0.999 -> design 2
    assert np.ravel_multi_index(res.designs[0].index, grid.shape) == 2
    assert res.designs[0].cost == pytest.approx(10 / 30 + 2 / 9)
    res_m = select_from_grids([grid], obj, method="milp")
    assert res_m.designs[0].index == res.designs[0].index
    obj = weighted({"flight-time": 1, "price": 10})
    assert np.ravel_multi_index(select_from_grids([grid], obj).designs[0].index, grid.shape) == 0


def test_weighted_si_sum_as_paper_d() -> None:
    tau = np.array([270, 240, 1, 1, 1, 1, 1, 1.0])
    roll = np.array([0.02, 0.045, 9, 9, 9, 9, 9, 9])
    grid = make_grid(time_constant_ms=tau, roll_inertia_kgm2=roll, pitch_inertia_kgm2=roll)
    obj = weighted({"time-constant": 1, "roll-inertia": 1, "pitch-inertia": 1}, "none")
    d = select_from_grids([grid], obj).designs[0]
    assert d.cost == pytest.approx(0.27 + 0.04)
    assert np.ravel_multi_index(d.index, grid.shape) == 0


def test_bad_requests() -> None:
    with pytest.raises(RequestError, match="unknown objective"):
        single("speed")
    with pytest.raises(RequestError, match="NAME=NUMBER"):
        parse_weights("price")
    with pytest.raises(RequestError, match="not a number"):
        parse_weights("price=abc")
    with pytest.raises(RequestError, match="unknown metric"):
        weighted({"speed": 1})
    with pytest.raises(RequestError, match=">= 0"):
        weighted({"price": -1})
    with pytest.raises(RequestError, match="minimum flight time"):
        select_from_grids([make_grid()], single("price"), Requirements(min_flight_time_min=-1))
    with pytest.raises(RequestError, match="unknown method"):
        select_from_grids([make_grid()], single("price"), method="magic")


def test_nan_metrics_are_never_chosen() -> None:
    ft = np.array([np.nan, 5, 1, 1, 1, 1, 1, 1.0])
    res = select_from_grids([make_grid(flight_time_min=ft)], single("flight-time"), method="milp")
    assert np.ravel_multi_index(res.designs[0].index, (2, 2, 2)) == 1


@settings(max_examples=30, deadline=None)
@given(
    seed=st.integers(0, 2**31 - 1),
    counts=st.lists(st.sampled_from([4, 6, 8]), min_size=1, max_size=3, unique=True),
    objective=st.sampled_from(["flight-time", "price", "time-constant", "weighted"]),
)
def test_property_milp_and_enumeration_pick_the_same_designs(seed, counts, objective) -> None:
    """Coarse random metrics (many ties, dominated twins): identical picks, never dominated."""
    rng = np.random.default_rng(seed)
    grids = []
    for n in counts:
        metrics = {k: rng.integers(1, 4, (3, 3, 2)).astype(float) for k in METRIC_KEYS}
        limit = Check("current", "A", rng.integers(0, 10, (3, 3, 2)).astype(float), np.asarray(7.0))
        grids.append(make_grid(n, (3, 3, 2), [limit], **metrics))
    obj = weighted({"flight-time": 1, "price": 1}) if objective == "weighted" else single(objective)
    a = select_from_grids(grids, obj, method="milp")
    b = select_from_grids(grids, obj, method="exact")
    assert [d.index for d in a.designs] == [d.index for d in b.designs]
    assert (a.best is None) == (b.best is None)
    for grid, d in zip(grids, a.designs, strict=True):
        if not d.feasible:
            continue
        ok = grid.feasible()
        cost = obj.cost(grid, None if objective != "weighted" else _ranges(grids, obj))
        assert cost[d.index] == cost[ok].min()
        # no feasible design is at least as good in the objective and every tie metric
        # and strictly better in one
        better_or_equal = ok & (cost <= cost[d.index])
        strictly = np.zeros(grid.shape, bool)
        for metric, sense in TIE_ORDER:
            v = grid.metrics[metric]
            mine = v[d.index]
            if sense == "max":
                better_or_equal &= v >= mine
                strictly |= v > mine
            else:
                better_or_equal &= v <= mine
                strictly |= v < mine
        assert not np.any(better_or_equal & (strictly | (cost < cost[d.index])))


def _ranges(grids, obj):
    from optimizer.solve.objectives import metric_ranges

    return metric_ranges(grids, [g.feasible() for g in grids], obj.metrics)
