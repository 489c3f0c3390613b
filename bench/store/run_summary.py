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

    def sql(self, mark: str, component: str, *, columns: tuple[str, ...], time_cast: str = ""
            ) -> tuple[str, list[Any]]:
        """This filter as an SQL ``WHERE`` with bound parameters, for a store's dialect:
        ``mark`` is its placeholder (``?`` or ``%s``); ``component`` the expression of one
        component, with two placeholders (the key, then the value), e.g.
        ``components->>%s = %s``; ``columns`` the plain columns the store can filter on;
        ``time_cast`` what follows a time placeholder (``::timestamptz``)."""
        clauses: list[str] = []
        params: list[Any] = []
        for col in columns:
            if getattr(self, col) is not None:
                clauses.append(f"{col} = {mark}")
                params.append(getattr(self, col))
        for key in ("motor", "propeller", "esc_mode"):
            if getattr(self, key) is not None:
                clauses.append(component)
                params += [key, getattr(self, key)]
        for value, op in ((self.since, ">="), (self.until, "<")):
            if value is not None:
                clauses.append(f"started_utc {op} {mark}{time_cast}")
                params.append(value)
        return (("WHERE " + " AND ".join(clauses)) if clauses else ""), params
