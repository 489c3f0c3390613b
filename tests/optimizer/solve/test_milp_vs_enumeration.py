"""The default MILP and exhaustive enumeration agree (shipped and random catalogs)."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from optimizer.catalogs.catalog import Catalog, load_catalog
from optimizer.solve import exhaustive, milp_exact
from optimizer.solve.objectives import OBJECTIVE_NAMES, single, weighted
from optimizer.solve.selection import Requirements, optimize
from tests.conftest import CATALOGS

SHIPPED = ("thesis-e", "thesis-d")  # thesis-robot is the mobile-robot model, not a multirotor


def _key(result):
    return [(d.actuators, d.feasible, d.propeller, d.motor, d.battery) for d in result.designs]


@pytest.mark.parametrize("name", SHIPPED)
@pytest.mark.parametrize("objective", OBJECTIVE_NAMES)
@pytest.mark.parametrize("payload", [0.0, 0.5, 1.5])
def test_shipped_catalogs_agree(fixtures_dir, name: str, objective: str, payload: float) -> None:
    catalog = load_catalog(CATALOGS / name)
    req = Requirements(payload_kg=payload)
    by_milp = optimize(catalog, single(objective), (4, 6, 8), req, "milp")
    by_enum = optimize(catalog, single(objective), (4, 6, 8), req, "exact")
    assert _key(by_milp) == _key(by_enum)
    assert (by_milp.best is None) == (by_enum.best is None)
    if by_milp.best is not None:
        assert by_milp.best.actuators == by_enum.best.actuators
    for d in by_milp.designs:
        if d.feasible:
            assert d.status == "optimal" and d.mip_gap == 0.0


def test_shipped_catalog_with_requirements_and_weights(fixtures_dir) -> None:
    catalog = load_catalog(CATALOGS / "thesis-e")
    cases = [
        (single("price"), Requirements(min_flight_time_min=40)),
        (single("flight-time"), Requirements(payload_kg=1.0, max_time_constant_ms=120)),
        (weighted({"flight-time": 0.5, "price": 0.5}), Requirements()),
        (
            weighted({"time-constant": 1, "roll-inertia": 1, "pitch-inertia": 1}, "none"),
            Requirements(payload_kg=0.5, min_flight_time_min=10),
        ),
    ]
    for objective, req in cases:
        a = optimize(catalog, objective, (4, 6, 8), req, "milp")
        b = optimize(catalog, objective, (4, 6, 8), req, "exact")
        assert _key(a) == _key(b)


def random_catalog(seed: int, n_p: int, n_m: int, n_b: int) -> Catalog:
    """A small physically plausible catalog (coarse values make ties likely)."""
    rng = np.random.default_rng(seed)
    d_in = rng.choice([8, 9, 10, 11, 12, 13, 14], n_p)
    props = pd.DataFrame(
        {
            "id": [f"P{i}" for i in range(n_p)],
            "name": "prop",
            "mass_g": np.round(0.12 * d_in**2 * rng.uniform(0.8, 1.2, n_p)),
            "diameter_m": d_in * 0.0254,
            "ct": rng.choice([0.10, 0.11, 0.12], n_p),
            "cp": rng.choice([0.06, 0.07, 0.08], n_p),
            "price": rng.choice([4.0, 5.0, 6.0], n_p),
        }
    )
    kv = rng.choice([380, 480, 600, 750, 900], n_m)
    motors = pd.DataFrame(
        {
            "id": [f"M{i}" for i in range(n_m)],
            "name": "motor",
            "kv_rpm_per_v": kv,
            "resistance_ohm": np.round(rng.uniform(0.05, 0.25, n_m), 3),
            "mass_g": rng.choice([60, 80, 111], n_m),
            "max_current_a": rng.choice([15, 20, 30], n_m),
            "max_power_w": rng.choice([200, 300, 400], n_m),
            "price": rng.choice([20.0, 30.0], n_m),
        }
    )
    cap = rng.choice([2200, 3300, 4000, 5000, 8000], n_b)
    batteries = pd.DataFrame(
        {
            "id": [f"B{i}" for i in range(n_b)],
            "name": "battery",
            "mass_g": np.round(cap * 0.078),
            "capacity_mah": cap,
            "cells": rng.choice([3, 4], n_b),
            "price": np.round(cap / 100.0),
            "c_rating": rng.choice([25, 40], n_b),
        }
    )
    return Catalog.from_frames(props, motors, batteries, source=f"random-{seed}")


@pytest.mark.parametrize("seed", range(6))
def test_random_catalogs_agree_on_every_objective(seed: int) -> None:
    catalog = random_catalog(seed, 7, 6, 5)
    payload = [0.0, 0.8, 2.0][seed % 3]
    for objective in OBJECTIVE_NAMES:
        req = Requirements(payload_kg=payload)
        a = optimize(catalog, single(objective), (4, 6, 8), req, "milp")
        b = optimize(catalog, single(objective), (4, 6, 8), req, "exact")
        assert _key(a) == _key(b), objective


@pytest.mark.parametrize("seed", range(3))
def test_drive_current_model_agrees_and_changes_the_numbers(fixtures_dir, seed: int) -> None:
    """With the drive's current (winding loss drawn from the battery) the MILP still
    equals enumeration, and flight times are shorter than with (E.67)."""
    from dataclasses import replace

    base = random_catalog(seed, 7, 6, 5) if seed else load_catalog(
        CATALOGS / "thesis-e")
    drive = replace(base, constants=base.constants.with_updates(current_model="drive"))
    for objective in OBJECTIVE_NAMES:
        a = optimize(drive, single(objective), (4, 6, 8), Requirements(), "milp")
        b = optimize(drive, single(objective), (4, 6, 8), Requirements(), "exact")
        assert _key(a) == _key(b), objective
    thesis = optimize(base, single("flight-time"), (4,), Requirements(), "exact").best
    lossy = optimize(drive, single("flight-time"), (4,), Requirements(), "exact").best
    if thesis is not None and lossy is not None:
        assert lossy.metrics["flight_time_min"] < thesis.metrics["flight_time_min"]


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    shape=st.tuples(st.integers(1, 6), st.integers(1, 6), st.integers(1, 6)),
    seed=st.integers(0, 2**31 - 1),
    levels=st.integers(2, 6),
    formulation=st.sampled_from(["block", "unit", "factored"]),
)
def test_property_milp_finds_the_enumerated_optimum(shape, seed, levels, formulation) -> None:
    """On random costs with many exact ties the MILP's value equals enumeration's."""
    rng = np.random.default_rng(seed)
    cost = rng.integers(0, levels, shape).astype(float) * 1.5 - 2.0
    feasible = rng.random(shape) < 0.7
    e = exhaustive.solve(cost, feasible)
    m = milp_exact.solve(cost, feasible, formulation=formulation)
    assert (e.index is None) == (m.index is None)
    if e.index is not None:
        assert m.value == e.value
        assert m.status == "optimal"
        assert feasible.ravel()[m.index]


@pytest.mark.parametrize("seed", [0, 1])
def test_objective_cutoff_is_exact_on_large_arrays(seed: int) -> None:
    """Above 2 x CUTOFF_SAMPLE combinations the two-phase solve finds the same optimum."""
    rng = np.random.default_rng(seed)
    shape = (40, 30, 25)  # 30,000 combinations
    cost = rng.integers(0, 500, shape).astype(float)
    feasible = rng.random(shape) < 0.8
    e = exhaustive.solve(cost, feasible)
    with_cutoff = milp_exact.solve(cost, feasible)
    without = milp_exact.solve(cost, feasible, cutoff=False)
    assert "cutoff" in with_cutoff.detail and "cutoff" not in without.detail
    assert with_cutoff.value == without.value == e.value
    assert with_cutoff.status == "optimal" and with_cutoff.mip_gap == 0.0
    assert with_cutoff.n_candidates == int(feasible.sum())
