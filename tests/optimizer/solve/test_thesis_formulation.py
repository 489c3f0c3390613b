"""Paper E's own MILP formulation: runs, is conservative, and is compared with the exact optimum."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from optimizer.catalogs.catalog import Catalog, load_catalog
from optimizer.errors import RequestError
from optimizer.model.design_model import evaluate_grid
from optimizer.solve.thesis_formulation import (
    THESIS_REGIONS,
    THESIS_VARIABLE_COUNTS,
    build_thesis_model,
    solve_thesis,
)

#: Paper E test cases: (objective, payload kg).
CASES = {"I": ("flight-time", 0.0), "II": ("flight-time", 1.5), "III": ("time-constant", 0.0)}
METRIC = {
    "flight-time": ("flight_time_min", max),
    "time-constant": ("time_constant_ms", min),
    "power": ("propeller_power_w", min),
    "price": ("price", min),
    "roll-inertia": ("roll_inertia_kgm2", min),
    "pitch-inertia": ("pitch_inertia_kgm2", min),
}


@pytest.fixture(scope="module")
def thesis_e() -> Catalog:
    return load_catalog(Path(__file__).resolve().parents[3] / "optimizer/data/catalogs/thesis-e")


def brute_force(catalog, n, objective, payload=0.0, min_ft=None, max_tau=None):
    """Independent oracle: best exact value over the feasible grid."""
    grid = evaluate_grid(catalog, n, payload)
    metric, pick = METRIC[objective]
    ok = grid.feasible()
    if min_ft is not None:
        ok &= grid.metrics["flight_time_min"] >= min_ft
    if max_tau is not None:
        ok &= grid.metrics["time_constant_ms"] <= max_tau
    return (pick(grid.metrics[metric][ok]) if ok.any() else None), grid


@pytest.mark.parametrize("n", [4, 6, 8])
@pytest.mark.parametrize("case", list(CASES))
def test_paper_e_cases_run_and_are_never_better_than_the_exact_optimum(thesis_e, case, n):
    objective, payload = CASES[case]
    r = solve_thesis(thesis_e, n, objective, payload_kg=payload)
    assert r.status == "optimal" and r.feasible
    best, _ = brute_force(thesis_e, n, objective, payload)
    metric, pick = METRIC[objective]
    chosen = r.exact[metric]
    assert r.exact["feasible"]
    # never better than the exact optimum; on these cases, with 10 regions, equal to it
    assert pick(chosen, best) == pytest.approx(best, rel=1e-12)
    assert chosen == pytest.approx(best, rel=1e-9)
    assert r.shortfall == pytest.approx(0.0, abs=1e-9)
    assert (r.propeller, r.motor, r.battery) in r.optimal_designs
    # quantities that are linear in the thesis formulation carry no linearisation error
    for key in ("price", "time_constant_ms", "total_mass_kg", "hover_rpm"):
        assert r.linearised[key] == pytest.approx(r.exact[key], rel=1e-7), key
    # the chords of the convex n^3 lie above it: power overestimated, flight time under
    assert 0.0 <= r.errors["propeller_power_w"] < 0.03
    assert -0.03 < r.errors["flight_time_min"] <= 1e-9
    for key in ("roll_inertia_kgm2", "pitch_inertia_kgm2"):
        assert 0.0 <= r.errors[key] + 1e-9 < 0.05


#: Table E.4 (indices i1..i3, j1..j12) for N_a = 4, 6, 8.
TABLE_E4 = {
    4: (241, 561, 881, 98, 100, 102, 104, 106, 108, 110, 112, 114, 274, 594, 914),
    6: (241, 721, 1201, 99, 102, 105, 108, 111, 114, 117, 120, 123, 283, 763, 1243),
    8: (241, 881, 1521, 100, 104, 108, 112, 116, 120, 124, 128, 130, 290, 930, 1570),
}


@pytest.mark.parametrize("n", [4, 6, 8])
def test_thesis_region_counts_reproduce_table_e4_booleans(thesis_e, n):
    built = build_thesis_model(thesis_e, n, "flight-time", regions=THESIS_REGIONS)
    m = built.model
    i1, i2, i3, *j = TABLE_E4[n]
    assert i3 + j[-1] == THESIS_VARIABLE_COUNTS[n]
    assert m.count("binary") == i3  # 11 components + 230 n^3 regions + 2 x N/2 x 160
    # Continuous sets of Table E.3 as sized by Table E.4 (j0 = 96 after x1..x96).
    j = [96, *j]
    table = {
        name: j[k + 1] - j[k]
        for k, name in enumerate(
            (
                "dist_roll",
                "dist_pitch",
                "dist2_roll",
                "dist2_pitch",
                "act_roll",
                "act_pitch",
                "frame_roll",
                "frame_pitch",
                "Lf",
                "z_roll",
                "z_pitch",
                "z_n3",
            )
        )
    }
    names = [v.name for v in m.variables if v.kind == "continuous"]

    def count(prefix: str) -> int:
        return sum(1 for name in names if name.startswith(prefix))

    half, P, M = n // 2, 4, 3
    # sets sized as in the table
    for key in ("dist_roll", "dist_pitch", "dist2_roll", "dist2_pitch"):
        assert count(key + "[") == table[key] == half
    # Table E.4's three z-sets hold 160, 80 N, 80 N values; the region Booleans are
    # 230 (n^3), 80 N (roll), 80 N (pitch): the two 80 N sets match our PWL z-sets.
    assert count("d2_roll[") == count("d2_pitch[") == i2 - i1 == table["z_pitch"]
    assert sorted(table[k] for k in ("z_roll", "z_pitch", "z_n3")) == [160, i2 - i1, i2 - i1]
    # sets the equations size differently from the table: (E.46)-(E.51) has one Rule 4
    # term per (propeller, motor) pair, (E.52)-(E.57) one per propeller, (E.23)-(E.25)
    # one frame length per propeller, and the n^3 approximation one z per region.
    assert count("act_roll[") == P * M * half and table["act_roll"] == half
    assert count("frame_roll[") == P * half and table["frame_roll"] == half
    assert count("Lf[") == P and table["Lf"] in (2, 3)
    assert count("n3.z") == i1 - 11 == THESIS_REGIONS["n3"]  # the table's 160-set


def test_power_objective_choice_differs_from_exact_only_through_linearisation(thesis_e):
    coarse = solve_thesis(thesis_e, 4, "power", regions=10)
    fine = solve_thesis(thesis_e, 4, "power", regions=40)
    best, _ = brute_force(thesis_e, 4, "power")
    # 10 y-equal regions on [0, n^2_max]: the first chord overestimates low-power designs
    assert coarse.exact_objective > best * 1.01
    assert coarse.shortfall > 0.01
    assert fine.exact_objective == pytest.approx(best, rel=1e-9)


def test_requirements_are_respected_and_conservative(thesis_e):
    r = solve_thesis(thesis_e, 4, "flight-time", max_time_constant_ms=130.0)
    best, _ = brute_force(thesis_e, 4, "flight-time", max_tau=130.0)
    assert r.exact["time_constant_ms"] <= 130.0
    assert r.exact["flight_time_min"] == pytest.approx(best, rel=1e-9)
    r = solve_thesis(thesis_e, 6, "price", min_flight_time_min=50.0)
    assert r.feasible and r.exact["flight_time_min"] >= r.linearised["flight_time_min"] >= 50.0


def test_unreachable_requirement_is_infeasible(thesis_e):
    r = solve_thesis(thesis_e, 4, "price", min_flight_time_min=1000.0)
    assert r.status == "infeasible" and not r.feasible
    assert r.exact_optimum is None and r.shortfall is None
    assert r.as_dict()["feasible"] is False


def test_bad_requests_raise_request_errors(thesis_e):
    with pytest.raises(RequestError, match="objective"):
        solve_thesis(thesis_e, 4, "speed")
    with pytest.raises(RequestError, match="regions"):
        solve_thesis(thesis_e, 4, "price", regions=0)


def _random_catalog(seed: int) -> Catalog:
    rng = np.random.default_rng(seed)
    P, M, B = 3, 2, 3
    props = pd.DataFrame(
        {
            "id": [f"P{i}" for i in range(P)],
            "name": "p",
            "mass_g": rng.uniform(8, 30, P),
            "diameter_m": rng.uniform(0.2, 0.4, P),
            "ct": rng.uniform(0.08, 0.13, P),
            "cp": rng.uniform(0.04, 0.08, P),
            "price": rng.uniform(3, 10, P),
        }
    )
    mots = pd.DataFrame(
        {
            "id": [f"M{i}" for i in range(M)],
            "name": "m",
            "kv_rpm_per_v": rng.uniform(300, 900, M),
            "resistance_ohm": rng.uniform(0.05, 0.3, M),
            "mass_g": rng.uniform(60, 150, M),
            "max_current_a": rng.uniform(15, 40, M),
            "max_power_w": rng.uniform(200, 500, M),
            "price": rng.uniform(20, 40, M),
            "inertia_kgm2": rng.uniform(1e-5, 5e-5, M),
        }
    )
    bats = pd.DataFrame(
        {
            "id": [f"B{i}" for i in range(B)],
            "name": "b",
            "mass_g": rng.uniform(200, 1200, B),
            "capacity_mah": rng.uniform(2000, 16000, B),
            "cells": 3,
            "price": rng.uniform(20, 100, B),
            "max_current_a": rng.uniform(60, 300, B),
        }
    )
    return Catalog.from_frames(props, mots, bats, source=f"random-{seed}")


@pytest.mark.parametrize("seed", range(4))
@pytest.mark.parametrize("objective", ["flight-time", "roll-inertia", "power"])
def test_random_catalogs_choice_is_feasible_and_never_beats_the_oracle(seed, objective):
    cat = _random_catalog(seed)
    r = solve_thesis(cat, 6, objective, payload_kg=0.5)
    best, _ = brute_force(cat, 6, objective, 0.5)
    if best is None:
        assert not r.feasible
        return
    assert r.feasible and r.exact["feasible"]
    metric, pick = METRIC[objective]
    assert pick(r.exact[metric], best) == pytest.approx(best, rel=1e-12)
    assert r.exact_optimum == pytest.approx(best, rel=1e-12)
    assert r.shortfall >= -1e-12


@pytest.mark.parametrize("n", [4, 8])
def test_weighted_paper_d_case_1_matches_brute_force(thesis_e, n):
    weights = {"time-constant": 1.0, "roll-inertia": 1.0, "pitch-inertia": 1.0}
    r = solve_thesis(thesis_e, n, weights)
    grid = evaluate_grid(thesis_e, n)
    cost = (
        grid.metrics["time_constant_ms"] * 1e-3
        + grid.metrics["roll_inertia_kgm2"]
        + grid.metrics["pitch_inertia_kgm2"]
    )
    best = cost[grid.feasible()].min()
    assert r.objective.startswith("weighted(")
    assert r.exact_optimum == pytest.approx(best, rel=1e-12)
    assert r.exact_objective >= best * (1 - 1e-12)
    # the linearised sum over-estimates the squared distances (chords of a convex map)
    assert r.linearised_objective >= r.exact_objective * (1 - 1e-9)


def test_weighted_flight_time_is_refused(thesis_e):
    with pytest.raises(RequestError, match="linear terms only"):
        solve_thesis(thesis_e, 4, {"flight-time": 1.0, "price": 1.0})


def test_design_entry_has_the_cli_keys(thesis_e):
    keys = {
        "actuators",
        "feasible",
        "propeller",
        "motor",
        "battery",
        "flight_time_min",
        "time_constant_ms",
        "price",
        "total_mass_kg",
        "hover_rpm",
        "propeller_power_w",
        "current_a",
        "roll_inertia_kgm2",
        "pitch_inertia_kgm2",
        "solve_time_s",
    }
    entry = solve_thesis(thesis_e, 4, "flight-time").design_entry()
    assert keys <= set(entry) and entry["feasible"] is True and entry["method"] == "thesis"
    assert entry["flight_time_min"] > entry["linearised"]["flight_time_min"]
    bad = solve_thesis(thesis_e, 4, "price", min_flight_time_min=1e4).design_entry()
    assert bad["feasible"] is False and bad["propeller"] is None and "reason" in bad


def test_large_catalogs_are_refused_with_a_clear_message(thesis_e, monkeypatch):
    import optimizer.solve.thesis_formulation as tf

    monkeypatch.setattr(tf, "MAX_COMBINATIONS", 47)  # thesis-e has 4 x 3 x 4 = 48
    with pytest.raises(RequestError, match=r"48 \(propeller, motor, battery\) combinations"):
        tf.solve_thesis(thesis_e, 4, "price")
