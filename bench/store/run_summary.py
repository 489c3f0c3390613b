"""A run as every store lists it: the row of `runs --json`, the web view's list."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from bench.errors import RigError

__all__ = ["BadFilter", "RunFilter", "RunSummary", "utc_bound"]


class BadFilter(RigError):
    """A run-list filter that is not valid (a date that is not one): the web view
    answers 422, a command exits 2, before any store is asked."""


def utc_bound(value: str, name: str) -> str:
    """``value`` (``YYYY-MM-DD`` or an ISO 8601 time; without a zone it is UTC) as an ISO
    time in UTC with milliseconds, the form run.json's ``started_utc`` has, so both
    stores compare it alike; ``BadFilter`` naming ``name`` when it is not a date."""
    from datetime import UTC, datetime

    from analysis.errors import excerpt

    try:
        when = datetime.fromisoformat(value)
    except (TypeError, ValueError):
        raise BadFilter(f"{name} {excerpt(value)}: expected a date YYYY-MM-DD or an ISO "
                        "time YYYY-MM-DDTHH:MM[:SS][Z]") from None
    if when.tzinfo is None:
        when = when.replace(tzinfo=UTC)
    return when.astimezone(UTC).isoformat(timespec="milliseconds")


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

    def __post_init__(self) -> None:
        """The dates checked and put in one form here, whoever builds the filter."""
        for name in ("since", "until"):
            value = getattr(self, name)
            if value is not None:
                object.__setattr__(self, name, utc_bound(value, name))

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
