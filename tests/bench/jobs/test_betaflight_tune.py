"""Betaflight's PIDs scaled to the design's tilt authority (bench.jobs.betaflight_tune)."""

from __future__ import annotations

from dataclasses import replace

from bench.jobs.betaflight_tune import MULTIPLIER_RANGE, pid_scale, tune_lines
from optimizer.catalogs.catalog import load_catalog
from optimizer.flight.design import design_index, setup
from optimizer.model.design_model import evaluate_grid


def test_the_reference_design_keeps_the_stock_tune_and_a_hotter_one_is_divided():
    cat = load_catalog("optimizer/data/catalogs/thesis-e")
    grid = evaluate_grid(cat, 4)
    vehicle, _ = setup(cat, grid, design_index(grid, "P1", "M2", "B1"))
    assert pid_scale(vehicle) == 100
    # twice the full speed: twice 1 / u_hover, twice the authority, half the PIDs
    fast = replace(vehicle, omega_max_rad_s=2 * vehicle.omega_max_rad_s)
    assert pid_scale(fast) == 50
    assert pid_scale(replace(vehicle, omega_max_rad_s=100 * vehicle.omega_max_rad_s)) == \
        MULTIPLIER_RANGE[0]
    assert [line for _, line in tune_lines(fast)] == [
        "set simplified_master_multiplier = 50", "simplified_tuning apply"]
