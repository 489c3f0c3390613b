"""A run as every store lists it: the row of `runs --json`, the web view's list."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

__all__ = ["RunFilter", "RunSummary"]


@dataclass(frozen=True)
class RunSummary:
    """A run as every store lists it (``data``: where its run folder lives)."""

    run_id: str
    bench: str
    sequence: str
    status: str
    samples: int
    data: str
    started_utc: str | None = None
    ended_utc: str | None = None
    rig: str = ""
    reason: str = ""
    operator: str = ""
    components: dict[str, Any] = field(default_factory=dict)

    def as_dict(self) -> dict[str, Any]:
        return {k: getattr(self, k) for k in self.__dataclass_fields__}


@dataclass(frozen=True)
class RunFilter:
    """What a run list may be narrowed by (None: any). Dates are ISO strings, UTC."""

    bench: str | None = None
    status: str | None = None
    sequence: str | None = None
    motor: str | None = None
    propeller: str | None = None
    esc_mode: str | None = None
    since: str | None = None  # started at or after
    until: str | None = None  # started before

    def matches(self, run: RunSummary) -> bool:
        comp = run.components
        return ((self.bench is None or run.bench == self.bench)
                and (self.status is None or run.status == self.status)
                and (self.sequence is None or run.sequence == self.sequence)
                and (self.motor is None or str(comp.get("motor", "")) == self.motor)
                and (self.propeller is None or str(comp.get("propeller", "")) == self.propeller)
                and (self.esc_mode is None or str(comp.get("esc_mode", "")) == self.esc_mode)
                and (self.since is None or (run.started_utc or "") >= self.since)
                and (self.until is None or (run.started_utc or "") < self.until))
