"""Missed samples per device, counted from the samples' own time stamps.

Every backend hands out time-stamped blocks, so one counter serves them all: NI-DAQmx
(samples lost to a buffer overrun leave a hole in the hardware-timed stamps), serial
boards and flight controllers (lost lines, failed polls), CAN telemetry (frames lost on
their broadcast period). A role's nominal period is the rate its device states
(``expect``) or, failing that, the mean interval of its first ``learn`` intervals. The
count is the deficit: ``round(span / period) + 1 - samples`` over the run (host-stamped
data arrives in bursts, so single intervals would count jitter), plus one per row whose
values are all NaN (a sensor that filled a lost sample). The longest gap between two
samples is kept too. The run records them in ``run.json``.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

__all__ = ["DropCounter"]


@dataclass
class _Role:
    period_s: float | None = None
    stated: bool = False
    first_t: float | None = None
    last_t: float | None = None
    n: int = 0
    early: list[float] = field(default_factory=list)  # stamps until the period is learned
    nan_rows: int = 0
    longest_gap_s: float = 0.0


def _all_nan_rows(values: Mapping[str, np.ndarray]) -> int:
    """Rows whose values are all NaN. A column whose sum is a number has no NaN, so the
    usual block costs one sum."""
    cols = [np.asarray(v, float) for v in values.values()]
    if not cols or any(not np.isnan(np.add.reduce(c)) for c in cols):
        return 0
    nan = np.isnan(cols[0])
    for c in cols[1:]:
        nan &= np.isnan(c)
    return int(np.count_nonzero(nan))


class DropCounter:
    """Per-role drop counts; ``update`` on every block read, ``summary`` at the end."""

    def __init__(self, learn: int = 50) -> None:
        self.learn = learn
        self._roles: dict[str, _Role] = {}

    def expect(self, role: str, rate_hz: float) -> None:
        """The rate the device states (samples/s); takes the place of learning."""
        if rate_hz > 0:
            r = self._roles.setdefault(role, _Role())
            r.period_s, r.stated = 1.0 / rate_hz, True

    def update(self, role: str, t_s: np.ndarray, values: Mapping[str, np.ndarray]) -> None:
        t = np.asarray(t_s, float)
        if t.size == 0:
            return
        r = self._roles.get(role)
        if r is None:
            r = self._roles[role] = _Role()
        r.nan_rows += _all_nan_rows(values)
        # this runs on every block of every device: no concatenation, no temporary stack
        if r.last_t is not None:
            r.longest_gap_s = max(r.longest_gap_s, float(t[0]) - r.last_t)
        if t.size > 1:
            r.longest_gap_s = max(r.longest_gap_s, float(np.subtract(t[1:], t[:-1]).max()))
        if r.first_t is None:
            r.first_t = float(t[0])
        r.last_t = float(t[-1])
        r.n += t.size
        if r.period_s is None:
            r.early.extend(t[: self.learn + 1 - len(r.early)].tolist())
            if len(r.early) > self.learn:
                self._learn(r)

    @staticmethod
    def _learn(r: _Role) -> None:
        if len(r.early) >= 2 and r.early[-1] > r.early[0]:
            r.period_s = (r.early[-1] - r.early[0]) / (len(r.early) - 1)
        r.early = []

    def summary(self) -> dict[str, Any]:
        """``dropped_samples``, ``longest_gap_s`` and ``drops`` per role (``run.json``)."""
        per: dict[str, dict[str, Any]] = {}
        for role, r in self._roles.items():
            if r.n == 0:
                continue
            if r.period_s is None:
                self._learn(r)  # a short run: judge on what there is
            missing = 0
            if r.period_s and r.first_t is not None and r.last_t is not None:
                missing = max(0, round((r.last_t - r.first_t) / r.period_s) + 1 - r.n)
            per[role] = {"dropped": missing + r.nan_rows, "missing": missing,
                         "nan_rows": r.nan_rows, "samples": r.n,
                         "longest_gap_s": round(r.longest_gap_s, 6),
                         "period_s": None if r.period_s is None else round(r.period_s, 9),
                         "period_from": "device" if r.stated else "first samples"}
        total = sum(p["dropped"] for p in per.values())
        longest = max((p["longest_gap_s"] for p in per.values()), default=0.0)
        return {"dropped_samples": int(total), "longest_gap_s": longest, "drops": per}
