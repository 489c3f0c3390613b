"""The modelling layer: expressions, constraints, arrays for milp, solve and read back."""

from __future__ import annotations

import itertools
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from optimizer.solve.milp_builder import Constraint, LinExpr, Model, quicksum


def test_expression_arithmetic_collects_terms() -> None:
    m = Model()
    x, y = m.continuous("x", 0, 2), m.continuous("y", -1, 3)
    e = 2 * x + y - 0.5 * x + 3 - (y - 1) / 2
    assert e.terms == {x: 1.5, y: 0.5}
    assert e.constant == pytest.approx(3.5)
    assert e.bounds() == pytest.approx((3.0, 8.0))
    assert (-e).bounds() == pytest.approx((-8.0, -3.0))
    assert quicksum([x, y, 1, 2 * x]).terms == {x: 3.0, y: 1.0}


def test_nonlinear_products_are_refused() -> None:
    m = Model()
    x, y = m.continuous("x"), m.continuous("y")
    with pytest.raises(TypeError, match="not linear"):
        _ = x * y  # type: ignore[operator]


def test_constraint_has_no_truth_value() -> None:
    m = Model()
    x = m.binary("x")
    c = x <= 1
    assert isinstance(c, Constraint)
    with pytest.raises(TypeError):
        bool(c)


def test_duplicate_names_and_empty_bounds_are_errors() -> None:
    m = Model("t")
    m.binary("a")
    with pytest.raises(ValueError, match="already exists"):
        m.binary("a")
    with pytest.raises(ValueError, match="empty"):
        m.continuous("b", 2, 1)
    with pytest.raises(KeyError, match="no variable 'zz'"):
        m.var("zz")


def test_variables_of_another_model_are_refused() -> None:
    a, b = Model("a"), Model("b")
    x = a.binary("x")
    with pytest.raises(ValueError, match="another model"):
        b.add(x <= 1)


def test_to_arrays_builds_sparse_rows_and_bounds() -> None:
    m = Model()
    x = m.binary("x")
    y = m.integer("y", 0, 5)
    z = m.continuous("z", -1, 1)
    m.add(x + 2 * y - z <= 4, name="le")
    m.add(y >= 1 + x, name="ge")
    m.add(x + z == 0.5, name="eq")
    m.maximize(3 * x + y)
    a = m.to_arrays()
    assert a.A.shape == (3, 3)
    np.testing.assert_allclose(a.A.toarray(), [[1, 2, -1], [-1, 1, 0], [1, 0, 1]])
    np.testing.assert_allclose(a.row_lb, [-np.inf, 1, 0.5])
    np.testing.assert_allclose(a.row_ub, [4, np.inf, 0.5])
    np.testing.assert_array_equal(a.integrality, [1, 1, 0])
    np.testing.assert_allclose(a.c, [-3, -1, 0])  # maximisation negated
    np.testing.assert_allclose(a.lb, [0, 0, -1])
    np.testing.assert_allclose(a.ub, [1, 5, 1])
    assert m.constraint_names == ("le", "ge", "eq")


def test_solve_matches_brute_force_on_a_small_integer_program() -> None:
    m = Model()
    x = m.integer("x", 0, 4)
    y = m.integer("y", 0, 4)
    b = m.binary("b")
    m.add(3 * x + 2 * y <= 11 + 2 * b)
    m.add(x - y <= 1)
    m.maximize(5 * x + 4 * y - 3 * b)
    sol = m.solve(time_limit=5)
    best = max(
        5 * xv + 4 * yv - 3 * bv
        for xv, yv, bv in itertools.product(range(5), range(5), range(2))
        if 3 * xv + 2 * yv <= 11 + 2 * bv and xv - yv <= 1
    )
    assert sol.status == "optimal"
    assert sol.objective == pytest.approx(best)
    assert sol.value(5 * x + 4 * y - 3 * b) == pytest.approx(best)
    assert m.check(sol.values) == []
    assert sol.n_vars == 3 and sol.n_constraints == 2


def test_objective_constant_is_reported() -> None:
    m = Model()
    x = m.continuous("x", 1, 2)
    m.minimize(LinExpr({x: 2.0}, 10.0))
    assert m.solve().objective == pytest.approx(12.0)


def test_infeasible_model_reports_status_and_no_values() -> None:
    m = Model()
    x = m.binary("x")
    m.add(x >= 2)
    sol = m.solve(time_limit=5)
    assert sol.status == "infeasible"
    assert not sol.has_solution and sol.objective is None


def test_check_names_violated_rows_and_bounds() -> None:
    m = Model()
    x = m.continuous("x", 0, 1)
    m.add(x <= 0.5, name="half")
    assert m.check({"x": 0.75}) == ["half"]
    assert m.check({"x": 2.0}) == ["x", "half"]


def test_solver_stdout_noise_goes_to_stderr() -> None:
    # HiGHS sometimes writes debug lines straight to fd 1; `optimize --json` must stay clean.
    code = (
        "import os\n"
        "from optimizer.solve.milp_builder import _stdout_to_stderr\n"
        "with _stdout_to_stderr():\n"
        "    os.write(1, b'solver noise\\n')\n"
        "print('clean')\n"
    )
    root = Path(__file__).resolve().parents[3]
    proc = subprocess.run(
        [sys.executable, "-c", code], cwd=root, capture_output=True, text=True, check=True
    )
    assert proc.stdout == "clean\n"
    assert "solver noise" in proc.stderr
