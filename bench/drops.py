"""Missed or late samples per device, counted from the samples' own time stamps.

Every backend hands out time-stamped blocks, so one counter serves them all: NI-DAQmx
(a buffer overrun loses samples: a hole in the hardware-timed stamps), serial boards and
flight controllers (a lost line or a late reply), CAN telemetry (a frame lost or late on
its broadcast period). A role's nominal period is the median interval of its first
``learn`` intervals; an interval longer than ``factor`` periods counts
``round(interval / period) - 1`` missed samples (at least one), and a row whose values
are all NaN (a sensor that filled a lost sample) counts as one. The run records the
total, the longest gap and the figures per role in ``run.json``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

__all__ = ["DropCounter"]


@dataclass
class _Role:
    last_t: float | None = None
    period_s: float | None = None
    pending: list[np.ndarray] = field(default_factory=list)
    n_pending: int = 0
    dropped: int = 0
    nan_rows: int = 0
    longest_gap_s: float = 0.0


class DropCounter:
    """Per-role drop counts; ``update`` on every block read, ``summary`` at the end."""

    def __init__(self, learn: int = 50, factor: float = 1.5) -> None:
        self.learn = learn
        self.factor = factor
        self._roles: dict[str, _Role] = {}

    def update(self, role: str, t_s: np.ndarray, values: Mapping[str, np.ndarray]) -> None:
        t = np.asarray(t_s, float)
        if t.size == 0:
            return
        r = self._roles.setdefault(role, _Role())
        cols = [np.asarray(v, float) for v in values.values()]
        if cols:
            r.nan_rows += int(np.all(np.isnan(np.vstack(cols)), axis=0).sum())
        dt = np.diff(t) if r.last_t is None else np.diff(np.concatenate(([r.last_t], t)))
        r.last_t = float(t[-1])
        if dt.size:
            r.longest_gap_s = max(r.longest_gap_s, float(dt.max()))
        if r.period_s is None:
            r.pending.append(dt)
            r.n_pending += dt.size
            if r.n_pending >= self.learn:
                self._learn(r)
            return
        r.dropped += self._count(dt, r.period_s)

    def _learn(self, r: _Role) -> None:
        dt = np.concatenate(r.pending) if r.pending else np.empty(0)
        r.pending, r.n_pending = [], 0
        positive = dt[dt > 0]
        if positive.size == 0:
            return
        r.period_s = float(np.median(positive))
        r.dropped += self._count(dt, r.period_s)

    def _count(self, dt: np.ndarray, period: float) -> int:
        late = dt[dt > self.factor * period]
        return int(np.maximum(np.rint(late / period) - 1, 1).sum()) if late.size else 0

    def summary(self) -> dict[str, Any]:
        """``dropped_samples``, ``longest_gap_s`` and ``drops`` per role (``run.json``)."""
        per: dict[str, dict[str, Any]] = {}
        for role, r in self._roles.items():
            if r.period_s is None and r.n_pending >= 3:
                self._learn(r)  # a short run: judge on what there is
            per[role] = {"dropped": r.dropped + r.nan_rows, "late_or_missing": r.dropped,
                         "nan_rows": r.nan_rows, "longest_gap_s": round(r.longest_gap_s, 6),
                         "period_s": None if r.period_s is None else round(r.period_s, 9)}
        total = sum(p["dropped"] for p in per.values())
        longest = max((p["longest_gap_s"] for p in per.values()), default=0.0)
        return {"dropped_samples": int(total),
                "longest_gap_s": longest if math.isfinite(longest) else None,
                "drops": per}
