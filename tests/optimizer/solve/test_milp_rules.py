"""Each rule's feasible set is exactly what the thesis says it is.

Small cases are enumerated: the Booleans and the continuous argument are fixed,
and the solver is asked for the smallest and largest value of the rule's output
(or just for feasibility). Every allowed combination must be reachable, every
disallowed one infeasible.
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from optimizer.solve.milp_builder import Model
from optimizer.solve.milp_rules import (
    breakpoints,
    exactly_one,
    piecewise_linear,
    rule1_product,
    rule4_product,
    rule19a,
    rule19b,
)

X_VALUES = (0.0, 0.3, 1.0, 1.7, 2.0)


def _solve_fixed(build, fixes: dict[str, float], target: str | None, sense: str = "min"):
    model, _ = build()
    for name, val in fixes.items():
        model.add(model.var(name) == val, name=f"fix:{name}")
    if target is not None:
        (model.minimize if sense == "min" else model.maximize)(model.var(target))
    return model.solve(time_limit=5)


def _minmax(build, fixes, target):
    lo = _solve_fixed(build, fixes, target, "min")
    hi = _solve_fixed(build, fixes, target, "max")
    if lo.status == "infeasible":
        assert hi.status == "infeasible"
        return None
    assert lo.status == hi.status == "optimal", (lo.message, hi.message)
    return lo.objective, hi.objective


@pytest.mark.parametrize("n", [1, 2, 4])
def test_exactly_one_allows_only_one_hot(n: int) -> None:
    def build():
        m = Model()
        ds = [m.binary(f"d{i}") for i in range(n)]
        exactly_one(m, ds, "one")
        return m, ds

    for bits in itertools.product((0, 1), repeat=n):
        sol = _solve_fixed(build, {f"d{i}": b for i, b in enumerate(bits)}, None)
        assert (sol.status == "optimal") == (sum(bits) == 1), bits


@pytest.mark.parametrize(("a", "b"), [(2.0, 1.0), (-1.5, 0.5), (3.0, -4.0)])
def test_rule1_forces_z_to_delta_times_f(a: float, b: float) -> None:
    def build():
        m = Model()
        d = m.binary("d")
        x = m.continuous("x", 0.0, 2.0)
        rule1_product(m, d, a * x + b, "z")
        return m, None

    for dv, xv in itertools.product((0, 1), X_VALUES):
        got = _minmax(build, {"d": dv, "x": xv}, "z")
        assert got is not None, (dv, xv)
        want = dv * (a * xv + b)
        assert got == pytest.approx((want, want), abs=1e-7)


def test_rule1_needs_bounded_f() -> None:
    m = Model()
    d = m.binary("d")
    x = m.continuous("x")  # ub = inf
    with pytest.raises(ValueError, match="unbounded"):
        rule1_product(m, d, x, "z")


@pytest.mark.parametrize(("a", "b"), [(2.0, -1.0), (1.0, 0.5), (-2.0, -0.5)])
def test_rule4_forces_z_to_and_of_deltas_times_f(a: float, b: float) -> None:
    n = 3

    def build():
        m = Model()
        ds = [m.binary(f"d{i}") for i in range(n)]
        x = m.continuous("x", 0.0, 2.0)
        rule4_product(m, ds, a * x + b, "z")
        return m, None

    for bits in itertools.product((0, 1), repeat=n):
        for xv in X_VALUES:
            fixes = {f"d{i}": v for i, v in enumerate(bits)} | {"x": xv}
            got = _minmax(build, fixes, "z")
            assert got is not None, (bits, xv)
            want = float(all(bits)) * (a * xv + b)
            assert got == pytest.approx((want, want), abs=1e-7), (bits, xv)


def test_rule4_with_constant_f_is_a_product_of_booleans() -> None:
    # E.35: x_49 = d1 d5 d8 * tau (a constant)
    def build():
        m = Model()
        ds = [m.binary(f"d{i}") for i in range(3)]
        rule4_product(m, ds, 0.161, "tau")
        return m, None

    for bits in itertools.product((0, 1), repeat=3):
        got = _minmax(build, {f"d{i}": v for i, v in enumerate(bits)}, "tau")
        assert got == pytest.approx((0.161 * all(bits),) * 2, abs=1e-9)


@pytest.mark.parametrize("f_low", [0.5, 1.0, 1.9])
def test_rule19a_clears_delta_when_f_below_limit(f_low: float) -> None:
    def build():
        m = Model()
        d = m.binary("d")
        x = m.continuous("x", 0.0, 2.0)
        rule19a(m, x, f_low, d, "r19a", eps=1e-6)
        return m, None

    for dv, xv in itertools.product((0, 1), X_VALUES):
        ok = _solve_fixed(build, {"d": dv, "x": xv}, None).status == "optimal"
        # [x <= f_L] -> d = 0, with the printed +eps tolerance at the limit
        assert ok == (dv == 0 or xv >= f_low - 1e-6), (dv, xv)


@pytest.mark.parametrize("f_up", [0.5, 1.0, 1.9])
def test_rule19b_clears_delta_when_f_above_limit(f_up: float) -> None:
    def build():
        m = Model()
        d = m.binary("d")
        x = m.continuous("x", 0.0, 2.0)
        rule19b(m, x, f_up, d, "r19b", eps=1e-3)
        return m, None

    for dv, xv in itertools.product((0, 1), (*X_VALUES, f_up)):
        ok = _solve_fixed(build, {"d": dv, "x": xv}, None).status == "optimal"
        # [x >= f_U] -> d = 0; with eps > 0 the limit itself is excluded (Paper E)
        assert ok == (dv == 0 or xv <= f_up - 1e-3), (dv, xv)


def test_rule19b_with_negative_eps_is_equation_2_61() -> None:
    # (2.61): d M + f <= L_max + M + eps, i.e. the upper limit is inclusive
    def build():
        m = Model()
        d = m.binary("d")
        x = m.continuous("x", 0.0, 2.0)
        rule19b(m, x, 1.0, d, "r", eps=-1e-5)
        return m, None

    assert _solve_fixed(build, {"d": 1, "x": 1.0}, None).status == "optimal"
    assert _solve_fixed(build, {"d": 1, "x": 1.01}, None).status == "infeasible"
    assert _solve_fixed(build, {"d": 0, "x": 2.0}, None).status == "optimal"


@pytest.mark.parametrize("spacing", ["x", "y"])
def test_piecewise_linear_equals_the_interpolant_everywhere(spacing: str) -> None:
    regions = 4

    def func(x):
        return np.asarray(x, float) ** 1.5

    def build():
        m = Model()
        x = m.continuous("x", 0.0, 3.0)
        pwl = piecewise_linear(m, x, func, 0.0, 3.0, regions, "g", spacing=spacing)
        y = m.continuous("y", -100, 100)
        m.add(y == pwl.y)
        return m, pwl

    _, pwl = build()
    assert len(pwl.deltas) == regions == len(pwl.zs)
    np.testing.assert_allclose(pwl.approx(pwl.breakpoints), func(pwl.breakpoints))
    if spacing == "y":
        np.testing.assert_allclose(np.diff(func(pwl.breakpoints)), func(3.0) / regions)
    for xv in np.concatenate([np.linspace(0, 3, 13), pwl.breakpoints]):
        got = _minmax(build, {"x": float(xv)}, "y")
        want = float(pwl.approx(xv))
        assert got == pytest.approx((want, want), abs=1e-6), xv


def test_piecewise_linear_reproduces_table_2_5() -> None:
    # Table 2.5: x^2 on [0, 10] with three regions
    m = Model()
    x = m.continuous("x", 0.0, 10.0)
    pwl = piecewise_linear(m, x, np.square, 0.0, 10.0, 3, "sq")
    np.testing.assert_allclose(pwl.breakpoints, [0, 10 / 3, 20 / 3, 10])
    np.testing.assert_allclose(pwl.slopes, [3.33, 10.0, 16.67], atol=0.01)
    np.testing.assert_allclose(pwl.offsets, [0.0, -22.22, -66.67], atol=0.01)


def test_piecewise_linear_region_boolean_is_the_active_region() -> None:
    def build():
        m = Model()
        x = m.continuous("x", 0.0, 6.0)
        piecewise_linear(m, x, np.square, 0.0, 6.0, 10, "c2")
        return m, None

    for xv, region in ((0.1, 1), (2.9, 5), (5.0, 9), (6.0, 10)):
        for i in range(1, 11):
            sol = _solve_fixed(build, {"x": xv, f"c2.d{i}": 1}, None)
            assert (sol.status == "optimal") == (i == region), (xv, i)


def test_piecewise_linear_rejects_x_outside_interval() -> None:
    m = Model()
    x = m.continuous("x", 0.0, 5.0)
    with pytest.raises(ValueError, match="outside the approximation interval"):
        piecewise_linear(m, x, np.square, 0.0, 4.0, 3, "g")


def test_breakpoints_y_spacing_needs_increasing_function() -> None:
    with pytest.raises(ValueError, match="increasing"):
        breakpoints(lambda x: -x, 0.0, 1.0, 3, "y")
