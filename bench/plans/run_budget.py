"""How long a run will take and how much it will write, checked before it starts.

A sequence is data, so a typo (``hold_s = 1e6``, ``--repeats 100000``) compiles into a
plan of days; on the simulated rig, which runs faster than real time, it wrote 1.1 GB in
30 s. The bench projects the plan's rig time and the size of its samples and refuses a
plan above :data:`MAX_PLAN_S` outright; above :data:`CONFIRM_PLAN_S` or
:data:`CONFIRM_BYTES` it prints the projection and needs ``--yes``. docs/bench.md states
the bounds.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from bench.errors import RigError

__all__ = ["CONFIRM_BYTES", "CONFIRM_PLAN_S", "MAX_PLAN_S", "Budget", "check_budget",
           "check_duration", "project"]

MAX_PLAN_S = 24 * 3600.0  # a longer run is split into several (a day of samples is ~37 GB)
CONFIRM_PLAN_S = 3600.0
CONFIRM_BYTES = 2e9
#: Bytes per recorded row (lz4 Parquet, the seven base columns and the step): 2.79 MB for
#: the 162 500 rows of a two-repeat Step 1 on the simulated rig.
BYTES_PER_ROW = 17.2
#: Row rate when the rig file does not state its load cell's rate: the simulated rig's and
#: Paper C's DAQ rate (25 kHz, section 2.2), the fastest load cell the bench reads.
DEFAULT_ROW_RATE_HZ = 25_000.0


@dataclass(frozen=True)
class Budget:
    """A plan's projected rig time and samples size."""

    duration_s: float
    rate_hz: float
    bytes: float

    def describe(self) -> str:
        return (f"projected {_duration(self.duration_s)} of rig time and about "
                f"{_size(self.bytes)} of samples ({self.rate_hz:g} rows/s)")


def row_rate_hz(rig: Any, base_role: str = "load_cell") -> float:
    """The rate of the rows a run records: the base sensor's ``rate_hz`` option if the rig
    file sets one, else :data:`DEFAULT_ROW_RATE_HZ` (an upper bound for slower boards)."""
    device = (getattr(rig, "devices", None) or {}).get(base_role)
    rate = (getattr(device, "options", None) or {}).get("rate_hz")
    return float(rate) if isinstance(rate, int | float) and rate > 0 else DEFAULT_ROW_RATE_HZ


def project(duration_s: float, rate_hz: float) -> Budget:
    return Budget(duration_s, rate_hz, duration_s * rate_hz * BYTES_PER_ROW)


def check_duration(duration_s: float, what: str, described: str = "") -> None:
    """Refuse (``RigError``, exit 2) a plan longer than :data:`MAX_PLAN_S`, whatever the
    rig: a sequence checks this from its repeat count before it builds its steps."""
    if duration_s > MAX_PLAN_S:
        described = described or f"projected {_duration(duration_s)} of rig time"
        raise RigError(f"{what}: {described}; longer than the {_duration(MAX_PLAN_S)} "
                       "a run may last: check the hold and repeat counts, or split it into "
                       "several runs")


def check_budget(budget: Budget, what: str, yes: bool) -> None:
    """Refuse (``RigError``, exit 2) a plan beyond the bounds; above the confirmation
    bounds only with ``yes``."""
    check_duration(budget.duration_s, what, budget.describe())
    if not yes and (budget.duration_s > CONFIRM_PLAN_S or budget.bytes > CONFIRM_BYTES):
        raise RigError(f"{what}: {budget.describe()}; pass --yes to run it (asked above "
                       f"{_duration(CONFIRM_PLAN_S)} or {_size(CONFIRM_BYTES)})")


def _duration(seconds: float) -> str:
    if seconds >= 3600.0:
        return f"{seconds / 3600.0:.3g} h"
    if seconds >= 60.0:
        return f"{seconds / 60.0:.3g} min"
    return f"{seconds:.3g} s"


def _size(n: float) -> str:
    for unit, scale in (("TB", 1e12), ("GB", 1e9), ("MB", 1e6)):
        if n >= scale:
            return f"{n / scale:.3g} {unit}"
    return f"{n / 1e3:.3g} kB"
