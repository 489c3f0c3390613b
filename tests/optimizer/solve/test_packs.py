"""Cells in series and parallel (optimizer.solve.packs): hand-computed packs, exact selection."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from bench.cli import main
from optimizer.catalogs.catalog import Catalog, load_catalog
from optimizer.errors import RequestError
from optimizer.model.design_model import evaluate_grid
from optimizer.solve.objectives import single
from optimizer.solve.packs import cells_of, optimize_packs, pack_frame, parse_counts, with_packs
from tests.conftest import CATALOGS, SIZINGLAB


@pytest.fixture
def thesis_e(fixtures_dir) -> Catalog:
    return load_catalog(CATALOGS / "thesis-e")


def test_pack_of_a_cell_by_hand(thesis_e) -> None:
    # B1 is 3 cells of 4 Ah, 309 g, 25.5, 100 A, 11.1 V: one cell 103 g, 8.5, 3.7 V
    cells = cells_of(thesis_e)
    b1 = cells.iloc[0]
    assert (b1["mass_kg"], b1["price"], b1["voltage_v"]) == pytest.approx((0.103, 8.5, 3.7))
    packs = pack_frame(cells.iloc[[0]], (4,), (3,))
    row = packs.iloc[0]
    assert row["id"] == "B1-4S3P"
    assert row["mass_kg"] == pytest.approx(12 * 0.103)
    assert row["capacity_ah"] == pytest.approx(3 * 4.0)
    assert row["cells"] == 4 and row["max_current_a"] == pytest.approx(300.0)
    assert row["nominal_voltage_v"] == pytest.approx(14.8)
    assert row["price"] == pytest.approx(12 * 8.5)


def test_3s2p_of_b1_is_b2(thesis_e) -> None:
    # B2 (3S 8000 mAh, 618 g, 200 A, 51) is exactly two strings of B1's cells
    sp = with_packs(thesis_e, (3,), (2,))
    k = sp.battery_ids.index("B1-3S2P")
    a = evaluate_grid(sp, 6)
    b = evaluate_grid(thesis_e, 6)
    for key in a.metrics:
        assert np.allclose(a.metrics[key][:, :, k], b.metrics[key][:, :, 1], rtol=1e-12), key


def test_voltage_enters_the_current_by_hand(thesis_e) -> None:
    sp = with_packs(thesis_e, (2, 5), (1,))
    g = evaluate_grid(sp, 4)
    s = sp.batteries["cells"].to_numpy(float)
    # (E.67): x18 = N x17 / B_V with B_V = S x 4.0 V in flight (Paper D section 2.1)
    expected = 4 * g.metrics["propeller_power_w"] / (s * 4.0)[None, None, :]
    assert np.allclose(g.metrics["current_a"], expected)
    q = sp.batteries["capacity_ah"].to_numpy(float)[None, None, :]
    assert np.allclose(g.metrics["flight_time_min"], 60 * q / expected)


def _random_catalog(seed: int) -> Catalog:
    rng = np.random.default_rng(seed)
    p, m, b = (int(v) for v in rng.integers(2, 5, 3))
    props = pd.DataFrame({
        "id": [f"P{i}" for i in range(p)], "name": "p",
        "mass_g": rng.uniform(8, 30, p), "diameter_m": rng.uniform(0.2, 0.4, p),
        "ct": rng.uniform(0.09, 0.13, p), "cp": rng.uniform(0.04, 0.08, p),
        "price": rng.uniform(3, 9, p)})
    mots = pd.DataFrame({
        "id": [f"M{i}" for i in range(m)], "name": "m",
        "kv_rpm_per_v": rng.uniform(300, 1200, m), "resistance_ohm": rng.uniform(0.05, 0.3, m),
        "mass_g": rng.uniform(50, 150, m), "max_current_a": rng.uniform(10, 40, m),
        "max_power_w": rng.uniform(150, 500, m), "price": rng.uniform(20, 40, m)})
    cells = rng.integers(1, 5, b)
    bats = pd.DataFrame({
        "id": [f"B{i}" for i in range(b)], "name": "b",
        "mass_g": cells * rng.uniform(40, 150, b), "capacity_mah": rng.uniform(1500, 6000, b),
        "cells": cells, "price": rng.uniform(10, 60, b), "c_rating": rng.uniform(10, 40, b)})
    return Catalog.from_frames(props, mots, bats, {"battery_voltage": "nominal",
                                                   "min_thrust_to_weight": 1.5})


@pytest.mark.parametrize("objective", ["flight-time", "time-constant", "price", "power", "mass"])
def test_milp_equals_enumeration_on_shipped_and_random_catalogs(objective, fixtures_dir) -> None:
    catalogs = [load_catalog(CATALOGS / n) for n in ("thesis-e", "thesis-d")]
    catalogs += [_random_catalog(seed) for seed in range(4)]
    for cat in catalogs:
        a = optimize_packs(cat, single(objective), (4, 6), method="milp", parallel=(1, 2, 3))
        b = optimize_packs(cat, single(objective), (4, 6), method="exact", parallel=(1, 2, 3))
        for da, db in zip(a.designs, b.designs, strict=True):
            assert da.feasible == db.feasible
            if da.feasible:
                assert (da.propeller, da.motor, da.battery) == (db.propeller, db.motor,
                                                                db.battery)
                assert da.cost == pytest.approx(db.cost, rel=1e-12)


def test_decomposition_equals_one_big_grid(thesis_e) -> None:
    # the per-S solves with the carried cutoff find the optimum of the whole S x P grid
    whole = with_packs(thesis_e, (2, 3, 4, 5, 6), (1, 2, 3, 4))
    for objective in ("flight-time", "time-constant", "price"):
        cost = []
        for n in (4, 8):
            g = evaluate_grid(whole, n)
            c = single(objective).cost(g)
            cost.append(float(np.nanmin(np.where(g.feasible(), c, np.nan))))
        res = optimize_packs(thesis_e, single(objective), (4, 8), method="milp")
        assert [d.cost for d in res.designs] == pytest.approx(cost, rel=1e-12)


def test_sizinglab_milp_equals_enumeration(shared_data) -> None:
    from optimizer.catalogs.sizinglab import import_sizinglab

    cat = import_sizinglab(SIZINGLAB)
    a = optimize_packs(cat, single("flight-time"), (4,), method="milp", series=(3, 4),
                       parallel=(1, 2))
    b = optimize_packs(cat, single("flight-time"), (4,), method="exact", series=(3, 4),
                       parallel=(1, 2))
    assert (a.designs[0].battery, a.designs[0].motor) == (b.designs[0].battery,
                                                           b.designs[0].motor)


def test_counts_and_cli_errors(capsys) -> None:
    assert parse_counts("2-4,6", "--series") == (2, 3, 4, 6)
    with pytest.raises(RequestError):
        parse_counts("4-2", "--series")
    with pytest.raises(RequestError):
        parse_counts("0-2", "--series")
    assert main(["optimize", "--parallel", "2"]) == 2
    assert "--parallel needs --series" in capsys.readouterr().err
    assert main(["optimize", "--series", "3-4", "--parallel", "1-2", "--actuators", "4"]) == 0
    out = capsys.readouterr().out
    assert "S1P" in out or "S2P" in out


def test_evaluate_takes_a_pack_id(capsys) -> None:
    import json

    assert main(["evaluate", "--actuators", "4", "--propeller", "P4", "--motor", "M1",
                 "--battery", "B1-3S2P", "--json"]) == 0
    pack = json.loads(capsys.readouterr().out)
    assert main(["evaluate", "--actuators", "4", "--propeller", "P4", "--motor", "M1",
                 "--battery", "B2", "--json"]) == 0
    b2 = json.loads(capsys.readouterr().out)
    assert pack["battery"] == "B1-3S2P"
    for key in ("flight_time_min", "total_mass_kg", "max_thrust_n", "hover_throttle_pct"):
        assert pack[key] == pytest.approx(b2[key], rel=1e-12)
