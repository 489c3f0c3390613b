"""A small modelling layer over ``scipy.optimize.milp`` (HiGHS).

The thesis writes its MILPs as ``min g^T x  s.t.  A x <= b`` (E.9-E.10) and builds
``A`` row by row from rules (section 2.4). This module lets the rules be written
as Python: named variables with bounds and a kind (binary, integer, continuous),
linear expressions with ``+ - *``, constraints with ``<= >= ==``, an objective,
and a build step to sparse arrays for ``milp``. Solutions are read back by name.

Example::

    m = Model("demo")
    x = m.binary("x")
    y = m.continuous("y", 0, 10)
    m.add(y <= 4 + 3 * x, name="cap")
    m.maximize(y - x)
    sol = m.solve(time_limit=5)
    sol["y"], sol.objective, sol.status   # 7.0, 6.0, 'optimal'
"""

from __future__ import annotations

import contextlib
import os
import sys
import time
from collections.abc import Iterable, Iterator, Mapping
from dataclasses import dataclass, field
from typing import Literal

import numpy as np
from scipy import sparse
from scipy.optimize import Bounds, LinearConstraint, milp

Kind = Literal["continuous", "integer", "binary"]
Sense = Literal["<=", ">=", "=="]

_INTEGRALITY = {"continuous": 0, "integer": 1, "binary": 1}


class Var:
    """One decision variable of a :class:`Model` (identity-hashed, so usable as a key)."""

    __slots__ = ("index", "kind", "lb", "model_id", "name", "ub")

    def __init__(self, model_id: int, index: int, name: str, kind: Kind, lb: float, ub: float):
        self.model_id = model_id
        self.index = index
        self.name = name
        self.kind = kind
        self.lb = lb
        self.ub = ub

    def __repr__(self) -> str:
        return f"Var({self.name!r}, {self.kind}, [{self.lb:g}, {self.ub:g}])"

    __hash__ = object.__hash__

    def expr(self) -> LinExpr:
        return LinExpr({self: 1.0})

    # arithmetic delegates to LinExpr
    def __add__(self, other: ExprLike) -> LinExpr:
        return self.expr() + other

    __radd__ = __add__

    def __sub__(self, other: ExprLike) -> LinExpr:
        return self.expr() - other

    def __rsub__(self, other: ExprLike) -> LinExpr:
        return as_expr(other) - self.expr()

    def __mul__(self, k: float) -> LinExpr:
        return self.expr() * k

    __rmul__ = __mul__

    def __truediv__(self, k: float) -> LinExpr:
        return self.expr() / k

    def __neg__(self) -> LinExpr:
        return -self.expr()

    def __le__(self, other: ExprLike) -> Constraint:  # type: ignore[override]
        return self.expr() <= other

    def __ge__(self, other: ExprLike) -> Constraint:  # type: ignore[override]
        return self.expr() >= other

    def __eq__(self, other: object) -> Constraint:  # type: ignore[override]
        return self.expr() == other  # type: ignore[return-value]


class LinExpr:
    """``sum(coef * var) + constant``; immutable from the caller's point of view."""

    __slots__ = ("constant", "terms")

    def __init__(self, terms: Mapping[Var, float] | None = None, constant: float = 0.0):
        self.terms: dict[Var, float] = dict(terms) if terms else {}
        self.constant = float(constant)

    def __repr__(self) -> str:
        parts = [f"{c:+g}*{v.name}" for v, c in self.terms.items()]
        return "LinExpr(" + " ".join([*parts, f"{self.constant:+g}"]) + ")"

    def copy(self) -> LinExpr:
        return LinExpr(self.terms, self.constant)

    def _iadd(self, other: ExprLike, sign: float) -> LinExpr:
        if isinstance(other, LinExpr):
            for v, c in other.terms.items():
                self.terms[v] = self.terms.get(v, 0.0) + sign * c
            self.constant += sign * other.constant
        elif isinstance(other, Var):
            self.terms[other] = self.terms.get(other, 0.0) + sign
        else:
            self.constant += sign * float(other)
        return self

    def __add__(self, other: ExprLike) -> LinExpr:
        return self.copy()._iadd(other, 1.0)

    __radd__ = __add__

    def __sub__(self, other: ExprLike) -> LinExpr:
        return self.copy()._iadd(other, -1.0)

    def __rsub__(self, other: ExprLike) -> LinExpr:
        return (-self)._iadd(other, 1.0)

    def __mul__(self, k: float) -> LinExpr:
        if isinstance(k, (Var, LinExpr)):
            raise TypeError(
                "product of two expressions is not linear; use a rule (optimizer.solve.milp_rules)"
            )
        k = float(k)
        return LinExpr({v: c * k for v, c in self.terms.items()}, self.constant * k)

    __rmul__ = __mul__

    def __truediv__(self, k: float) -> LinExpr:
        return self * (1.0 / float(k))

    def __neg__(self) -> LinExpr:
        return self * -1.0

    def __le__(self, other: ExprLike) -> Constraint:  # type: ignore[override]
        return Constraint(self - other, "<=")

    def __ge__(self, other: ExprLike) -> Constraint:  # type: ignore[override]
        return Constraint(self - other, ">=")

    def __eq__(self, other: object) -> Constraint:  # type: ignore[override]
        return Constraint(self - other, "==")  # type: ignore[operator]

    __hash__ = None  # type: ignore[assignment]

    def bounds(self) -> tuple[float, float]:
        """Interval (min, max) of the expression over the variables' bounds."""
        lo = hi = self.constant
        for v, c in self.terms.items():
            if c == 0.0:
                continue
            a, b = (c * v.lb, c * v.ub) if c > 0 else (c * v.ub, c * v.lb)
            lo += a
            hi += b
        return lo, hi

    def value(self, values: Mapping[Var, float] | np.ndarray) -> float:
        """Evaluate at a solution (array indexed by ``Var.index``, or a mapping)."""
        if isinstance(values, np.ndarray):
            return self.constant + sum(c * values[v.index] for v, c in self.terms.items())
        return self.constant + sum(c * values[v] for v, c in self.terms.items())


ExprLike = LinExpr | Var | float | int


def as_expr(x: ExprLike) -> LinExpr:
    """Any expression-like value as a :class:`LinExpr` (a copy for expressions)."""
    if isinstance(x, LinExpr):
        return x.copy()
    if isinstance(x, Var):
        return x.expr()
    return LinExpr(constant=float(x))


def quicksum(items: Iterable[ExprLike]) -> LinExpr:
    """Sum many expressions in place (``sum()`` copies at every step)."""
    out = LinExpr()
    for item in items:
        out._iadd(item, 1.0)
    return out


@dataclass
class Constraint:
    """``expr (sense) 0``; built by comparing expressions, named when added."""

    expr: LinExpr
    sense: Sense
    name: str = ""

    def __bool__(self) -> bool:
        raise TypeError("a Constraint has no truth value; add it to a Model with Model.add")


@dataclass(frozen=True)
class MilpArrays:
    """The arrays ``scipy.optimize.milp`` takes: min c@x, lb_A <= A@x <= ub_A."""

    c: np.ndarray
    integrality: np.ndarray
    lb: np.ndarray
    ub: np.ndarray
    A: sparse.csr_array
    row_lb: np.ndarray
    row_ub: np.ndarray
    objective_constant: float
    objective_sign: float

    @property
    def shape(self) -> tuple[int, int]:
        # scipy's stubs leave a sparse array's shape optional; a built matrix has one
        return self.A.shape  # pyright: ignore[reportReturnType]


@dataclass(frozen=True)
class Solution:
    """Result of :meth:`Model.solve`: status, objective and values by variable name."""

    status: Literal["optimal", "time_limit", "infeasible", "unbounded", "error"]
    message: str
    objective: float | None
    values: dict[str, float]
    solve_time_s: float
    mip_gap: float | None = None
    n_vars: int = 0
    n_constraints: int = 0

    @property
    def has_solution(self) -> bool:
        return bool(self.values)

    def __getitem__(self, name: str) -> float:
        return self.values[name]

    def get(self, name: str, default: float | None = None) -> float | None:
        return self.values.get(name, default)

    def value(self, item: ExprLike) -> float:
        """Value of a variable or expression of the solved model."""
        if isinstance(item, Var):
            return self.values[item.name]
        expr = as_expr(item)
        return expr.constant + sum(c * self.values[v.name] for v, c in expr.terms.items())


@contextlib.contextmanager
def _stdout_to_stderr() -> Iterator[None]:
    """Send C-level writes to fd 1 to stderr for the duration.

    HiGHS occasionally prints debug lines to stdout on its own (e.g.
    "HighsMipSolverData::transformNewIntegerFeasibleSolution ..."), which would corrupt
    machine-readable output such as ``rotorbench optimize --json``.
    """
    try:
        fd = sys.stdout.fileno()
    except (AttributeError, OSError, ValueError):  # no real stdout (e.g. captured)
        yield
        return
    sys.stdout.flush()
    saved = os.dup(fd)
    try:
        os.dup2(sys.stderr.fileno(), fd)
        yield
    finally:
        os.dup2(saved, fd)
        os.close(saved)


_STATUS = {0: "optimal", 1: "time_limit", 2: "infeasible", 3: "unbounded", 4: "error"}


@dataclass
class Model:
    """Variables, constraints and one linear objective; solved with HiGHS via ``milp``."""

    name: str = "model"
    _vars: list[Var] = field(default_factory=list)
    _by_name: dict[str, Var] = field(default_factory=dict)
    _rows: list[int] = field(default_factory=list)
    _cols: list[int] = field(default_factory=list)
    _data: list[float] = field(default_factory=list)
    _row_lb: list[float] = field(default_factory=list)
    _row_ub: list[float] = field(default_factory=list)
    _row_names: list[str] = field(default_factory=list)
    _objective: LinExpr = field(default_factory=LinExpr)
    _sense: Literal["min", "max"] = "min"

    # -- variables -------------------------------------------------------
    def add_var(
        self, name: str, lb: float = 0.0, ub: float = np.inf, kind: Kind = "continuous"
    ) -> Var:
        """A new variable; names are unique within a model."""
        if name in self._by_name:
            raise ValueError(f"variable {name!r} already exists in model {self.name!r}")
        if kind not in _INTEGRALITY:
            raise ValueError(f"kind must be continuous, integer or binary, got {kind!r}")
        if kind == "binary":
            lb, ub = 0.0, 1.0
        lb, ub = float(lb), float(ub)
        if np.isnan(lb) or np.isnan(ub) or lb > ub:
            raise ValueError(f"variable {name!r}: bounds [{lb}, {ub}] are empty")
        v = Var(id(self), len(self._vars), name, kind, lb, ub)
        self._vars.append(v)
        self._by_name[name] = v
        return v

    def binary(self, name: str) -> Var:
        return self.add_var(name, kind="binary")

    def integer(self, name: str, lb: float = 0.0, ub: float = np.inf) -> Var:
        return self.add_var(name, lb, ub, kind="integer")

    def continuous(self, name: str, lb: float = 0.0, ub: float = np.inf) -> Var:
        return self.add_var(name, lb, ub, kind="continuous")

    def var(self, name: str) -> Var:
        """The variable called ``name`` (KeyError naming it if absent)."""
        try:
            return self._by_name[name]
        except KeyError:
            raise KeyError(f"no variable {name!r} in model {self.name!r}") from None

    def __contains__(self, name: str) -> bool:
        return name in self._by_name

    @property
    def variables(self) -> tuple[Var, ...]:
        return tuple(self._vars)

    @property
    def n_vars(self) -> int:
        return len(self._vars)

    def count(self, kind: Kind | None = None) -> int:
        """Number of variables, optionally of one kind."""
        if kind is None:
            return len(self._vars)
        return sum(1 for v in self._vars if v.kind == kind)

    # -- constraints -----------------------------------------------------
    @property
    def n_constraints(self) -> int:
        return len(self._row_lb)

    @property
    def constraint_names(self) -> tuple[str, ...]:
        return tuple(self._row_names)

    def add(self, constraint: Constraint, name: str = "") -> int:
        """Add one constraint; returns its row index."""
        if not isinstance(constraint, Constraint):
            raise TypeError(f"expected a Constraint (e.g. x <= 3), got {type(constraint).__name__}")
        expr = constraint.expr
        row = len(self._row_lb)
        for v, c in expr.terms.items():
            if v.model_id != id(self):
                raise ValueError(f"variable {v.name!r} belongs to another model")
            if c != 0.0:
                self._rows.append(row)
                self._cols.append(v.index)
                self._data.append(c)
        rhs = -expr.constant
        lo, hi = {"<=": (-np.inf, rhs), ">=": (rhs, np.inf), "==": (rhs, rhs)}[constraint.sense]
        self._row_lb.append(lo)
        self._row_ub.append(hi)
        self._row_names.append(name or constraint.name or f"r{row}")
        return row

    def add_all(self, constraints: Iterable[Constraint], name: str = "") -> list[int]:
        return [self.add(c, f"{name}[{i}]" if name else "") for i, c in enumerate(constraints)]

    # -- objective -------------------------------------------------------
    def minimize(self, expr: ExprLike) -> None:
        self._objective, self._sense = as_expr(expr), "min"

    def maximize(self, expr: ExprLike) -> None:
        self._objective, self._sense = as_expr(expr), "max"

    # -- build and solve -------------------------------------------------
    def to_arrays(self) -> MilpArrays:
        """Sparse arrays for ``milp`` (a maximisation is negated into a minimisation)."""
        n = len(self._vars)
        sign = -1.0 if self._sense == "max" else 1.0
        c = np.zeros(n)
        for v, k in self._objective.terms.items():
            c[v.index] += sign * k
        A = sparse.csr_array(
            sparse.coo_array(
                (np.asarray(self._data, float), (np.asarray(self._rows), np.asarray(self._cols))),
                shape=(self.n_constraints, n),
            )
        )
        A.sum_duplicates()
        return MilpArrays(
            c=c,
            integrality=np.array([_INTEGRALITY[v.kind] for v in self._vars], dtype=np.uint8),
            lb=np.array([v.lb for v in self._vars], float),
            ub=np.array([v.ub for v in self._vars], float),
            A=A,
            row_lb=np.asarray(self._row_lb, float),
            row_ub=np.asarray(self._row_ub, float),
            objective_constant=self._objective.constant,
            objective_sign=sign,
        )

    def solve(
        self,
        time_limit: float | None = 60.0,
        mip_rel_gap: float = 0.0,
        presolve: bool = True,
        extra_options: Mapping[str, object] | None = None,
    ) -> Solution:
        """Solve with HiGHS. ``mip_rel_gap=0`` asks for a proven optimum (see design notes)."""
        arrays = self.to_arrays()
        options: dict[str, object] = {"presolve": presolve, "mip_rel_gap": mip_rel_gap}
        if time_limit is not None:
            options["time_limit"] = float(time_limit)
        if extra_options:
            options.update(extra_options)
        # scipy's LinearConstraint and Bounds are unannotated: the checker takes lb and ub to
        # be floats, the type of their defaults (-inf, inf); they take arrays
        constraints = (
            [LinearConstraint(arrays.A, arrays.row_lb, arrays.row_ub)]  # pyright: ignore[reportArgumentType]
            if self.n_constraints else []
        )
        t0 = time.perf_counter()
        with _stdout_to_stderr():
            res = milp(
                arrays.c,
                integrality=arrays.integrality,
                bounds=Bounds(arrays.lb, arrays.ub),  # pyright: ignore[reportArgumentType]
                constraints=constraints,
                options=dict(options),  # milp mutates its options dict
            )
        elapsed = time.perf_counter() - t0
        status = _STATUS.get(int(res.status), "error")
        values: dict[str, float] = {}
        objective = None
        if res.x is not None:
            x = np.asarray(res.x, float)
            for v in self._vars:
                val = float(x[v.index])
                if v.kind != "continuous":
                    val = float(np.round(val))
                values[v.name] = val
            objective = float(self._objective.value(x))
        gap = getattr(res, "mip_gap", None)
        return Solution(
            status=status,  # type: ignore[arg-type]
            message=str(res.message),
            objective=objective,
            values=values,
            solve_time_s=elapsed,
            mip_gap=None if gap is None else float(gap),
            n_vars=self.n_vars,
            n_constraints=self.n_constraints,
        )

    def check(self, values: Mapping[str, float], tol: float = 1e-6) -> list[str]:
        """Names of constraints and bounds violated by ``values`` (all variables named)."""
        x = np.array([values[v.name] for v in self._vars], float)
        bad = [v.name for v in self._vars if x[v.index] < v.lb - tol or x[v.index] > v.ub + tol]
        arrays = self.to_arrays()
        ax = arrays.A @ x
        viol = (ax < arrays.row_lb - tol) | (ax > arrays.row_ub + tol)
        bad += [self._row_names[i] for i in np.flatnonzero(viol)]
        return bad

    def __iter__(self) -> Iterator[Var]:
        return iter(self._vars)
