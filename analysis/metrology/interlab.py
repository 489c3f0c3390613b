"""Benches compared as the participants of an interlaboratory comparison (ISO/IEC 17043).

Why: a lab with several benches must know whether they measure the same motor the same
way before it pools their constants. Each bench's value of a constant comes with its
expanded uncertainty U (k = 2, JCGM 100 6.2.1); every pair of benches gets the normalised
error E_n = (x1 - x2) / sqrt(U1^2 + U2^2) (``analysis.metrology.gum.normalised_error``),
and |E_n| > 1 flags the pair: their difference is larger than their uncertainties
explain (ISO/IEC 17043, as ISO/IEC Guide 43-1 before it). A value without an uncertainty
gives no E_n: it is listed, never judged. E_n assumes the two results independent.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from itertools import combinations
from typing import Any

from analysis.metrology.gum import COVERAGE_K, Budget, normalised_error

__all__ = ["EN_LIMIT", "ConstantComparison", "Pair", "Participant", "compare_constant",
           "flagged_benches"]

#: |E_n| above this: the pair disagrees (ISO/IEC 17043).
EN_LIMIT = 1.0


@dataclass(frozen=True)
class Participant:
    """One bench's value of one constant; ``budget`` None: no uncertainty is known."""

    bench: str
    value: float
    budget: Budget | None = None
    run_id: str = ""

    @property
    def u(self) -> float | None:
        """Standard uncertainty (k = 1)."""
        return None if self.budget is None else self.budget.u

    @property
    def expanded(self) -> float | None:
        """U = k u, k = 2."""
        return None if self.budget is None else COVERAGE_K * self.budget.u

    def as_dict(self) -> dict[str, Any]:
        return {"bench": self.bench, "value": self.value, "u": self.u, "U": self.expanded,
                "k": COVERAGE_K, "run_id": self.run_id,
                "budget": [t.as_dict() for t in self.budget.terms] if self.budget else None}


@dataclass(frozen=True)
class Pair:
    """Two benches on one constant: E_n of the first against the second."""

    bench_a: str
    bench_b: str
    e_n: float | None  # None: one of them has no uncertainty

    @property
    def flagged(self) -> bool:
        return self.e_n is not None and abs(self.e_n) > EN_LIMIT

    def as_dict(self) -> dict[str, Any]:
        return {"a": self.bench_a, "b": self.bench_b, "e_n": self.e_n,
                "flagged": self.flagged}


@dataclass(frozen=True)
class ConstantComparison:
    """Every bench's value of one constant and every pair's E_n."""

    name: str
    unit: str
    participants: tuple[Participant, ...]
    pairs: tuple[Pair, ...]

    @property
    def flagged(self) -> tuple[Pair, ...]:
        return tuple(p for p in self.pairs if p.flagged)

    def as_dict(self) -> dict[str, Any]:
        counts = flagged_benches(self)
        return {"constant": self.name, "unit": self.unit,
                "benches": [{**p.as_dict(), "flagged_pairs": counts[p.bench]}
                            for p in self.participants],
                "pairs": [p.as_dict() for p in self.pairs]}


def _e_n(a: Participant, b: Participant) -> float | None:
    if a.expanded is None or b.expanded is None:
        return None
    return normalised_error(a.value, a.expanded, b.value, b.expanded)


def compare_constant(name: str, unit: str, participants: Iterable[Participant]
                     ) -> ConstantComparison:
    """E_n of every pair of ``participants`` (in their order, each pair once)."""
    parts = tuple(participants)
    pairs = tuple(Pair(a.bench, b.bench, _e_n(a, b)) for a, b in combinations(parts, 2))
    return ConstantComparison(name, unit, parts, pairs)


def flagged_benches(comparison: ConstantComparison) -> dict[str, int]:
    """How many flagged pairs each bench of one constant is in (0 for none). A bench
    flagged against every other stands apart from them; with two benches both are, and the
    comparison cannot say which one is off."""
    counts = {p.bench: 0 for p in comparison.participants}
    for pair in comparison.flagged:
        counts[pair.bench_a] += 1
        counts[pair.bench_b] += 1
    return counts
