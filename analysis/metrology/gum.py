"""Uncertainty budgets in the manner of the GUM (JCGM 100:2008).

A budget is a list of terms, each a standard uncertainty already multiplied by its
sensitivity coefficient (the term's contribution to the result, in the result's unit).
Independent terms add in quadrature (GUM 5.1.2); the effective degrees of freedom follow
Welch-Satterthwaite (GUM G.4.1), and the expanded uncertainty is U = k u_c with k = 2 by
default, as calibration certificates state it (GUM 6.2.1).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from typing import Any

__all__ = ["COVERAGE_K", "Budget", "Term", "normalised_error", "rectangular"]

#: The coverage factor every expanded uncertainty is printed with (about 95 %).
COVERAGE_K = 2.0


def rectangular(half_width: float) -> float:
    """Standard uncertainty of a quantity known only to lie within +-half_width (GUM 4.3.7)."""
    return abs(half_width) / math.sqrt(3.0)


@dataclass(frozen=True)
class Term:
    """One line of a budget: its contribution u_i = |c_i| u(x_i) in the result's unit."""

    name: str
    u: float
    kind: str  # "A" (statistics of repeated observations) or "B" (other knowledge)
    dof: float = math.inf  # degrees of freedom of u (Type A: n - 1; Type B: infinite)
    note: str = ""

    def as_dict(self) -> dict[str, Any]:
        return {"name": self.name, "u": self.u, "type": self.kind,
                "dof": None if math.isinf(self.dof) else self.dof, "note": self.note}


@dataclass(frozen=True)
class Budget:
    """The terms of one constant's standard uncertainty, and what they combine to."""

    value: float
    unit: str
    terms: tuple[Term, ...] = field(default_factory=tuple)

    @property
    def u(self) -> float:
        """Combined standard uncertainty u_c: independent terms in quadrature."""
        return math.sqrt(sum(t.u * t.u for t in self.terms))

    @property
    def expanded(self) -> float:
        """U = k u_c, k = 2."""
        return COVERAGE_K * self.u

    @property
    def dof_eff(self) -> float:
        """Welch-Satterthwaite: u_c^4 / sum(u_i^4 / nu_i); infinite when every term is."""
        den = sum(t.u ** 4 / t.dof for t in self.terms if t.u > 0 and not math.isinf(t.dof))
        return math.inf if den == 0 else self.u ** 4 / den

    def plus(self, *terms: Term) -> Budget:
        return Budget(self.value, self.unit, self.terms + tuple(terms))

    def as_dict(self) -> dict[str, Any]:
        dof = self.dof_eff
        return {"value": self.value, "unit": self.unit, "u": self.u,
                "U": self.expanded, "k": COVERAGE_K,
                "dof_eff": None if math.isinf(dof) else dof,
                "budget": [t.as_dict() for t in self.terms]}

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> Budget:
        terms = tuple(Term(str(t["name"]), float(t["u"]), str(t["type"]),
                           math.inf if t.get("dof") is None else float(t["dof"]),
                           str(t.get("note", "")))
                      for t in data.get("budget", ()))
        return cls(float(data["value"]), str(data.get("unit", "")), terms)

    @classmethod
    def of(cls, value: float, unit: str, terms: Iterable[Term]) -> Budget:
        return cls(value, unit, tuple(terms))


def normalised_error(x1: float, big_u1: float, x2: float, big_u2: float) -> float:
    """E_n = (x1 - x2) / sqrt(U1^2 + U2^2), U at k = 2: |E_n| <= 1 agrees (ISO/IEC 17043)."""
    den = math.hypot(big_u1, big_u2)
    if den == 0:
        return math.inf if x1 != x2 else 0.0
    return (x1 - x2) / den
