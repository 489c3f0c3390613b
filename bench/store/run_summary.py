"""A run as every store lists it: the row of `runs --json`, the web view's list."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

__all__ = ["RunSummary"]


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
