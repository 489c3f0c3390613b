"""The thesis' mixed-logical rules as building blocks on :mod:`optimizer.solve.milp_builder`.

Section 2.4 and Paper E section 3 take these rules from Bemporad & Morari (1999)
and Mignone (2002); each function below adds exactly the rows the thesis prints:

* :func:`exactly_one` -- "the sum of the deltas equals one" (2.51), (E.13)-(E.15);
* :func:`rule1_product` -- Rule 1, ``z = delta * f(x)``;
* :func:`rule4_product` -- Rule 4, ``z = (delta_1 and ... and delta_n) * f(x)``;
* :func:`rule19a` -- Rule 19a, ``[f(x) <= f_L] -> [delta = 0]``;
* :func:`rule19b` -- Rule 19b, ``[f(x) >= f_U] -> [delta = 0]``;
* :func:`piecewise_linear` -- the "nonlinear positive function" approximation of
  Paper E section 3 and section 2.4.1.2 with N regions, one Boolean per region.

``m`` and ``M`` are the minimum and maximum of ``f(x)`` over the variables' box;
by default they are computed from the variable bounds (interval arithmetic), so
every continuous variable used in ``f`` needs finite bounds.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Literal, cast

import numpy as np
from scipy.optimize import brentq

from optimizer.solve.milp_builder import ExprLike, LinExpr, Model, Var, as_expr, quicksum

#: default epsilon of Rules 19a/19b: the thesis says "machine precision"; HiGHS works
#: to a feasibility tolerance of 1e-6, so anything smaller is the same as zero.
EPS = 1e-6


def _range(f: LinExpr, m: float | None, M: float | None, what: str) -> tuple[float, float]:
    lo, hi = f.bounds()
    m = lo if m is None else float(m)
    M = hi if M is None else float(M)
    if not (np.isfinite(m) and np.isfinite(M)):
        names = ", ".join(v.name for v in f.terms)
        raise ValueError(f"{what}: f(x) is unbounded; give finite bounds to {names} or pass m, M")
    return m, M


def exactly_one(model: Model, deltas: Sequence[Var], name: str) -> int:
    """Select exactly one of ``deltas``: sum(delta) == 1 (2.51), (E.13)-(E.15)."""
    if not deltas:
        raise ValueError(f"{name}: empty selection set")
    return model.add(quicksum(deltas) == 1, name=name)


def rule1_product(
    model: Model,
    delta: Var,
    f: ExprLike,
    name: str,
    m: float | None = None,
    M: float | None = None,
) -> Var:
    """Rule 1: a new variable ``z = delta * f(x)`` (four rows, section 2.4 / Paper E).

    -M d + z <= 0;  m d - z <= 0;  -m d + z <= f - m;  M d - z <= -f + M
    """
    f = as_expr(f)
    m, M = _range(f, m, M, name)
    z = model.continuous(name, min(0.0, m), max(0.0, M))
    model.add(-M * delta + z <= 0, name=f"{name}:r1a")
    model.add(m * delta - z <= 0, name=f"{name}:r1b")
    model.add(-m * delta + z <= f - m, name=f"{name}:r1c")
    model.add(M * delta - z <= -f + M, name=f"{name}:r1d")
    return z


def rule4_product(
    model: Model,
    deltas: Sequence[Var],
    f: ExprLike,
    name: str,
    m: float | None = None,
    M: float | None = None,
) -> Var:
    """Rule 4: a new variable ``z = (AND deltas) * f(x)`` (Paper E section 3).

    With ``Mt = max(0, -m)`` and ``mt = min(0, -M)``, as printed:
    z + Mt sum(d) <= f + n Mt;  z <= f + Mt;  -z - mt sum(d) <= -f - n mt;
    -z <= -f - mt;  z + mt d_i <= 0;  -z - Mt d_i <= 0  (for every i).
    """
    if not deltas:
        raise ValueError(f"{name}: Rule 4 needs at least one delta")
    f = as_expr(f)
    m, M = _range(f, m, M, name)
    n = len(deltas)
    Mt, mt = max(0.0, -m), min(0.0, -M)
    z = model.continuous(name, min(0.0, m), max(0.0, M))
    s = quicksum(deltas)
    model.add(z + Mt * s <= f + n * Mt, name=f"{name}:r4a")
    model.add(z <= f + Mt, name=f"{name}:r4b")
    model.add(-z - mt * s <= -f - n * mt, name=f"{name}:r4c")
    model.add(-z <= -f - mt, name=f"{name}:r4d")
    for i, d in enumerate(deltas):
        model.add(z + mt * d <= 0, name=f"{name}:r4e{i}")
        model.add(-z - Mt * d <= 0, name=f"{name}:r4f{i}")
    return z


def rule19a(
    model: Model,
    f: ExprLike,
    f_low: float,
    delta: Var,
    name: str,
    eps: float = EPS,
    big_m: float | None = None,
) -> int:
    """Rule 19a: ``[f(x) <= f_L] -> [delta = 0]``, i.e. ``M delta <= f - f_L + M + eps``.

    With ``delta = 1`` this leaves ``f >= f_L - eps``: Paper E prints ``+eps``;
    eq. (2.60) of section 2.4.1 is the same row with ``eps = 0``. ``big_m`` defaults
    to the smallest value that leaves ``delta = 0`` unconstrained (``f_L - m``).
    """
    f = as_expr(f)
    if big_m is None:
        m, _ = _range(f, None, None, name)
        big_m = max(f_low - m, 0.0)
    return model.add(big_m * delta <= f - f_low + big_m + eps, name=name)


def rule19b(
    model: Model,
    f: ExprLike,
    f_up: float,
    delta: Var,
    name: str,
    eps: float = EPS,
    big_m: float | None = None,
) -> int:
    """Rule 19b: ``[f(x) >= f_U] -> [delta = 0]``, i.e. ``M delta <= -f + f_U + M - eps``.

    With ``delta = 1`` this leaves ``f <= f_U - eps`` (Paper E). Eq. (2.61) of
    section 2.4.1 prints the same row with ``+eps`` (an inclusive upper limit):
    call it with ``eps=-eps``. ``big_m`` defaults to the smallest valid ``M - f_U``.
    """
    f = as_expr(f)
    if big_m is None:
        _, M = _range(f, None, None, name)
        big_m = max(M - f_up, 0.0) + max(eps, 0.0)
    return model.add(big_m * delta <= -f + f_up + big_m - eps, name=name)


@dataclass(frozen=True)
class PiecewiseLinear:
    """What :func:`piecewise_linear` added: ``y ~ g(x)`` and its parts per region."""

    y: LinExpr
    deltas: tuple[Var, ...]
    zs: tuple[Var, ...]
    breakpoints: np.ndarray
    slopes: np.ndarray
    offsets: np.ndarray
    #: g at the breakpoints (the interpolant's nodes)
    values: np.ndarray

    def approx(self, x: float | np.ndarray) -> np.ndarray | float:
        """The interpolant the MILP uses, evaluated outside the solver."""
        return np.interp(x, self.breakpoints, self.values)


def breakpoints(
    func: Callable[[np.ndarray], np.ndarray],
    x_min: float,
    x_max: float,
    regions: int,
    spacing: Literal["x", "y"] = "x",
) -> np.ndarray:
    """Region limits: equal length on the x-axis (section 2.4.1.2) or on the y-axis.

    Paper E (Fig. E.3) spaces the regions equally on the y-axis; that needs ``func``
    strictly increasing on ``[x_min, x_max]`` and inverts it numerically.
    """
    if regions < 1:
        raise ValueError(f"regions must be >= 1, got {regions}")
    if not x_max > x_min:
        raise ValueError(f"empty interval [{x_min}, {x_max}]")
    if spacing == "x":
        return np.linspace(x_min, x_max, regions + 1)
    if spacing != "y":
        raise ValueError(f"spacing must be 'x' or 'y', got {spacing!r}")

    def g(x: float) -> float:
        # func is written for arrays and called on numpy scalars (which act as 0-d arrays)
        return float(func(np.float64(x)))  # pyright: ignore[reportArgumentType]

    y0, y1 = g(x_min), g(x_max)
    if not y1 > y0:
        raise ValueError("y-spacing needs a strictly increasing function")
    xs = [x_min]
    for k in range(1, regions):
        target = y0 + (y1 - y0) * k / regions
        xs.append(cast(float, brentq(lambda t, tg=target: g(t) - tg, x_min, x_max)))  # a root
    xs.append(x_max)
    return np.asarray(xs, float)


def piecewise_linear(
    model: Model,
    x: ExprLike,
    func: Callable[[np.ndarray], np.ndarray],
    x_min: float,
    x_max: float,
    regions: int,
    name: str,
    spacing: Literal["x", "y"] = "x",
    eps: float = EPS,
) -> PiecewiseLinear:
    """Approximate ``y = func(x)`` on ``[x_min, x_max]`` with ``regions`` line segments.

    Per region ``i`` with limits ``X1 < X2``: slope ``a = (g(X2) - g(X1)) / (X2 - X1)``
    (2.57), offset ``b = g(X1) - a X1`` (2.58), a Boolean ``delta_i`` and
    ``z_i = delta_i (a x + b)`` by Rule 1; Rule 19a clears ``delta_i`` when
    ``x < X1`` (2.60) and Rule 19b when ``x > X2 + eps`` (2.61); exactly one
    region is active and ``y = sum z_i``. The region conditions are on ``x``
    (section 2.4.1); Paper E states them on ``z_i``, which is the same set for an
    increasing ``g``. Both ends of a region are inclusive, so ``x_max`` is feasible
    (Rule 19b as printed in Paper E, with ``-eps``, would exclude it).
    """
    x = as_expr(x)
    lo, hi = x.bounds()
    if lo < x_min - 1e-9 * max(1.0, abs(x_min)) or hi > x_max + 1e-9 * max(1.0, abs(x_max)):
        raise ValueError(
            f"{name}: x ranges over [{lo:g}, {hi:g}], outside the approximation interval "
            f"[{x_min:g}, {x_max:g}]; tighten the variable bounds"
        )
    bp = breakpoints(func, x_min, x_max, regions, spacing)
    gv = np.asarray(func(bp), float)
    slopes = np.diff(gv) / np.diff(bp)  # (2.57)
    offsets = gv[:-1] - slopes * bp[:-1]  # (2.58)
    deltas, zs = [], []
    for i in range(regions):
        d = model.binary(f"{name}.d{i + 1}")
        deltas.append(d)
        seg = slopes[i] * x + offsets[i]
        zs.append(rule1_product(model, d, seg, f"{name}.z{i + 1}"))
        rule19a(model, x, bp[i], d, f"{name}.lo{i + 1}", eps=0.0)  # (2.60)
        rule19b(model, x, bp[i + 1], d, f"{name}.hi{i + 1}", eps=-eps)  # (2.61)
    exactly_one(model, deltas, f"{name}.one")
    return PiecewiseLinear(
        y=quicksum(zs),
        deltas=tuple(deltas),
        zs=tuple(zs),
        breakpoints=bp,
        slopes=slopes,
        offsets=offsets,
        values=gv,
    )
