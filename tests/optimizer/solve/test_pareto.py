"""Exact Pareto fronts: epsilon-constraint MILP = enumeration = brute force; the CLI."""

from __future__ import annotations

import json

import numpy as np
import pytest

from bench.cli import main
from optimizer.solve.pareto import enumerate_front, is_nondominated, milp_front
from optimizer.solve.selection import ENTRY_KEYS
from tests.conftest import CATALOGS


def brute_force(cx: np.ndarray, cy: np.ndarray, ok: np.ndarray) -> list[tuple[float, float]]:
    x, y = cx.ravel(), cy.ravel()
    f = np.flatnonzero(ok.ravel())
    nd = [i for i in f if not any(
        x[j] <= x[i] and y[j] <= y[i] and (x[j] < x[i] or y[j] < y[i]) for j in f)]
    return sorted({(x[i], y[i]) for i in nd})


@pytest.mark.parametrize("seed", range(25))
def test_milp_front_equals_enumeration_and_brute_force(seed: int) -> None:
    rng = np.random.default_rng(seed)
    shape = tuple(int(v) for v in rng.integers(1, 6, 3))
    # integer costs make exact ties, which the front must collapse to one design
    cx = rng.integers(0, 6, shape).astype(float) if seed % 2 else rng.random(shape)
    cy = rng.integers(0, 6, shape).astype(float) if seed % 3 else rng.random(shape)
    ok = rng.random(shape) < 0.8
    a, b = enumerate_front(cx, cy, ok), milp_front(cx, cy, ok)
    assert a.indices.tolist() == b.indices.tolist()
    got = [(cx.ravel()[i], cy.ravel()[i]) for i in b.indices]
    assert sorted(got) == brute_force(cx, cy, ok)
    assert b.solves == 2 * len(b.indices) + 1


def run(capsys, *argv: str) -> dict:
    assert main(["pareto", *argv, "--json"]) == 0
    return json.loads(capsys.readouterr().out)


def test_thesis_e_four_actuators_front(capsys, tmp_path) -> None:
    png = tmp_path / "front.png"
    doc = run(capsys, "--actuators", "4", "--x", "flight-time", "--y", "time-constant",
              "--check", "--plot", str(png))
    front = doc["front"]
    assert len(front) >= 3 and doc["per_actuator"][0]["check_agrees"]
    for d in front:
        assert list(d)[: len(ENTRY_KEYS)] == list(ENTRY_KEYS)
    ft = np.array([d["flight_time_min"] for d in front])
    tau = np.array([d["time_constant_ms"] for d in front])
    assert is_nondominated(-ft, tau)
    for objective, end in (("flight-time", front[0]), ("time-constant", front[-1])):
        assert main(["optimize", "--actuators", "4", "--objective", objective, "--json"]) == 0
        best = json.loads(capsys.readouterr().out)["best"]
        for key in ("propeller", "motor", "battery", "flight_time_min", "time_constant_ms"):
            assert end[key] == best[key]
    assert png.stat().st_size > 1000
    # by default every design of the front hovers with margin; under the thesis' rules (no
    # thrust limit) the fast end P1/M1/B3 cannot hover on its own datasheet
    assert doc["warnings"] == [] and doc["hover_margin"]["min_thrust_to_weight"] == 1.2
    thesis = run(capsys, "--actuators", "4", "--thesis-rules")
    hovering = {(d["propeller"], d["motor"], d["battery"]) for d in thesis["front"][:2]}
    assert all(p_m_b not in w for w in thesis["warnings"] for p_m_b in map("/".join, hovering))
    assert any("P1/M1/B3: cannot hover" in w for w in thesis["warnings"])


def test_merged_front_over_actuator_counts_is_not_dominated(capsys, fixtures_dir) -> None:
    from optimizer.catalogs.catalog import load_catalog
    from optimizer.model.design_model import evaluate_grid

    cat_dir = CATALOGS / "thesis-d"
    doc = run(capsys, "--catalog", str(cat_dir), "--x", "price", "--y", "flight-time",
              "--check")
    assert all(e["check_agrees"] for e in doc["per_actuator"])
    cat = load_catalog(cat_dir)
    everything = []
    for n in (4, 6, 8):
        g = evaluate_grid(cat, n)
        ok = g.feasible()
        everything += list(zip(g.metrics["price"][ok], -g.metrics["flight_time_min"][ok],
                               strict=True))
    pts = np.array(everything)
    for d in doc["front"]:
        p, f = d["price"], -d["flight_time_min"]
        dominated = (pts[:, 0] <= p) & (pts[:, 1] <= f) & ((pts[:, 0] < p) | (pts[:, 1] < f))
        assert not dominated.any()
    assert is_nondominated(np.array([d["price"] for d in doc["front"]]),
                           -np.array([d["flight_time_min"] for d in doc["front"]]))


def test_pareto_errors(capsys) -> None:
    assert main(["pareto", "--x", "price", "--y", "price"]) == 2
    assert "two different objectives" in capsys.readouterr().err
