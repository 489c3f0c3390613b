"""Measured actuator constants in SQLite beside the run index (``<root>/constants.sqlite``).

One row per actuator (motor, propeller, ESC, ESC mode, battery/supply) and kind of fit:
``step`` rows hold the fitted latency and time constants of a step run, ``static`` rows
the static curves of a sweep and the supply current at a list of thrusts. Every row
names the run it came from; storing a newer fit of the same kind replaces the old row.
The optimizer reads them through ``bench.store.measured_constants.load_measured``; the rows
are fitted by ``bench.store.constants_fit.fit_for_store``.
"""

from __future__ import annotations

import json
import sqlite3
from collections.abc import Mapping
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from bench.errors import RigError
from bench.store.json_values import json_safe
from bench.store.sqlite_store import connect, writing

__all__ = ["KEY_FIELDS", "STORE_NAME", "ActuatorKey", "ConstantsRow", "ConstantsStore"]

STORE_NAME = "constants.sqlite"
KEY_FIELDS = ("motor", "propeller", "esc", "esc_mode", "battery")
_SCHEMA = """
CREATE TABLE IF NOT EXISTS constants (
    motor TEXT NOT NULL,
    propeller TEXT NOT NULL,
    esc TEXT NOT NULL,
    esc_mode TEXT NOT NULL,
    battery TEXT NOT NULL,
    kind TEXT NOT NULL,
    catalog TEXT,
    run_id TEXT NOT NULL,
    run_path TEXT NOT NULL,
    fitted_utc TEXT NOT NULL,
    data TEXT NOT NULL,
    PRIMARY KEY (motor, propeller, esc, esc_mode, battery, kind)
)
"""


@dataclass(frozen=True)
class ActuatorKey:
    """What the constants belong to (ids of the optimizer catalog where there is one)."""

    motor: str
    propeller: str
    esc: str
    esc_mode: str
    battery: str
    catalog: str = ""

    @classmethod
    def from_components(cls, components: Mapping[str, Any], where: str) -> ActuatorKey:
        missing = [k for k in KEY_FIELDS if not components.get(k)]
        if missing:
            raise RigError(f"{where}: run.json components lack {missing}: cannot key the "
                           "constants (motor, propeller, esc, esc_mode, battery)")
        return cls(*(str(components[k]) for k in KEY_FIELDS),
                   catalog=str(components.get("catalog") or ""))


@dataclass(frozen=True)
class ConstantsRow:
    key: ActuatorKey
    kind: str  # step | static
    run_id: str
    run_path: str
    fitted_utc: str
    data: dict[str, Any]


class ConstantsStore:
    """A small SQLite table; every call opens its own short connection."""

    def __init__(self, root: Path) -> None:
        self.root = Path(root)
        self.path = self.root / STORE_NAME

    def _connect(self) -> sqlite3.Connection:
        try:
            self.root.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise RigError(f"{self.root}: cannot create the constants folder "
                           f"({exc.strerror or exc})") from None
        return connect(self.path, _SCHEMA, "constants store", "move it away and store the "
                       "runs again with `rotorbench constants --add RUN`")

    def put(self, key: ActuatorKey, kind: str, run_id: str, run_path: str,
            data: Mapping[str, Any]) -> None:
        """Store (or replace) the constants of one kind for one actuator."""
        if kind not in ("step", "static"):
            raise ValueError(f"kind must be step or static, got {kind!r}")
        text = json.dumps(json_safe(data), allow_nan=False)
        now = datetime.now(UTC).isoformat(timespec="seconds")
        with writing(self.path, "constants store"), self._connect() as con:
            con.execute(
                "INSERT OR REPLACE INTO constants VALUES (?,?,?,?,?,?,?,?,?,?,?)",
                (key.motor, key.propeller, key.esc, key.esc_mode, key.battery, kind,
                 key.catalog, run_id, str(run_path), now, text))

    def rows(self) -> list[ConstantsRow]:
        if not self.path.exists():
            return []
        with self._connect() as con:
            cur = con.execute(
                "SELECT motor, propeller, esc, esc_mode, battery, catalog, kind, run_id, "
                "run_path, fitted_utc, data FROM constants ORDER BY motor, propeller, esc, "
                "esc_mode, battery, kind")
            out = []
            for m, p, e, mode, b, cat, kind, rid, rpath, utc, data in cur.fetchall():
                try:
                    values = json.loads(data)
                except json.JSONDecodeError as exc:
                    raise RigError(f"{self.path}: constants of ({m}, {p}, {mode}) {kind}: "
                                   f"invalid JSON ({exc.msg})") from None
                out.append(ConstantsRow(ActuatorKey(m, p, e, mode, b, cat or ""), kind, rid,
                                        rpath, utc, values))
            return out
