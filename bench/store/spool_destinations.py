"""Where each spooled run is going: its catalog and data location, recorded before it starts.

A spool is one folder per user, shared by every catalog that user records into, so where a
run goes is what its recording command was told, not what ``store sync`` is told later.
Before a lab command records anything it writes a ledger entry,
``<spool>/.destinations/<pid>-<ns>.json``: the catalog's identity (the UUID ``store init``
wrote into it) and the data location (none: the catalog's own, read at delivery). A run of
that process (run.json's ``pid``, started at or after the entry) goes there and only there.
The ledger, not the run folder, holds it because the run folder is made by the recorder,
which knows no store, and because a run killed at its first sample must still know it.

A catalog that could not be reached when the command started has no known UUID: the entry
keeps its connection parameters without any secret (host, port, dbname, user, sslmode...;
never a password) and the first ``store sync`` that reaches that catalog (the same host
by any of its names, port and database) writes the UUID in. Without ``--store``, ``store
sync`` connects to each entry's own parameters, libpq taking the password from
``PGPASSWORD``, ``~/.pgpass`` or the service file, as the bench's own commands do.
"""

from __future__ import annotations

import contextlib
import json
import os
import socket
import time
from collections.abc import Mapping
from dataclasses import asdict, dataclass, field, replace
from datetime import datetime
from pathlib import Path
from typing import Any

from bench.errors import RigError
from bench.store.store_url import SECRET_KEYS

__all__ = ["LEDGER", "Destination", "Ledger", "same_address"]

LEDGER = ".destinations"
_PG_PORT = "5432"


@dataclass(frozen=True)
class Destination:
    """Where the runs of process ``pid`` recorded since ``since`` (epoch s) go."""

    pid: int
    since: float
    catalog_id: str | None  # None: the catalog was away when the command started
    params: dict[str, str] = field(default_factory=dict)  # no secret, ever
    data: str | None = None  # None: the catalog's data location (store init --data)
    path: Path | None = field(default=None, compare=False)

    def as_json(self) -> dict[str, Any]:
        out = asdict(self)
        out.pop("path")
        return out


class Ledger:
    """The destinations of a spool's runs (read once per ``Ledger``)."""

    def __init__(self, spool: Path) -> None:
        self.folder = Path(spool) / LEDGER
        self._entries: list[Destination] | None = None

    def record(self, *, catalog_id: str | None, params: Mapping[str, str],
               data: str | None) -> Destination:
        """Write this process's entry (atomically); a spool that cannot take it is refused
        before anything spins."""
        clean = {k: str(v) for k, v in params.items() if k not in SECRET_KEYS}
        dest = Destination(os.getpid(), time.time(), catalog_id, clean, data)
        path = self.folder / f"{dest.pid}-{time.time_ns()}.json"
        try:
            self.folder.mkdir(parents=True, exist_ok=True)
            _write(path, dest.as_json())
        except OSError as exc:
            raise RigError(f"spool {self.folder.parent}: cannot record where its runs go "
                           f"({exc.strerror or exc})") from None
        self._entries = None
        return replace(dest, path=path)

    def entries(self) -> list[Destination]:
        if self._entries is None:
            found = []
            for path in sorted(self.folder.glob("*.json")):
                with contextlib.suppress(OSError, UnicodeDecodeError, ValueError, TypeError,
                                         KeyError):
                    doc = json.loads(path.read_text(encoding="utf-8"))
                    found.append(Destination(int(doc["pid"]), float(doc["since"]),
                                             doc.get("catalog_id"), dict(doc.get("params") or {}),
                                             doc.get("data"), path))
            self._entries = found
        return self._entries

    def of(self, meta: Mapping[str, Any]) -> Destination | None:
        """The destination of the run whose run.json is ``meta``: its process's latest entry
        written before the run started; None for a run no lab command recorded."""
        pid, started = meta.get("pid"), _epoch(meta.get("started_utc"))
        if not isinstance(pid, int) or started is None:
            return None
        mine = [d for d in self.entries() if d.pid == pid and d.since <= started + 1.0]
        return max(mine, key=lambda d: d.since) if mine else None

    def resolve(self, dest: Destination, catalog_id: str) -> Destination:
        """``dest`` now known to be the catalog ``catalog_id`` (written back)."""
        done = replace(dest, catalog_id=catalog_id)
        if dest.path is not None:
            _write(dest.path, done.as_json())
        self._entries = None
        return done


def _write(path: Path, doc: Mapping[str, Any]) -> None:
    tmp = path.with_name(f".{path.name}.tmp")
    tmp.write_text(json.dumps(doc), encoding="utf-8")
    os.replace(tmp, path)


def _epoch(text: Any) -> float | None:
    try:
        return datetime.fromisoformat(str(text)).timestamp()
    except ValueError:
        return None


def same_address(a: Mapping[str, str], b: Mapping[str, str]) -> bool:
    """True when two sets of connection parameters name the same database on the same
    server: same port (5432 unless given) and database, and hosts that are the same text
    or resolve to a shared address (``localhost`` and ``127.0.0.1``). A service name is
    compared as such when neither names a host."""
    if not (a.get("host") or b.get("host")):
        return bool(a.get("service")) and a.get("service") == b.get("service") and \
            a.get("dbname") == b.get("dbname")
    if (a.get("port") or _PG_PORT) != (b.get("port") or _PG_PORT):
        return False
    if (a.get("dbname") or a.get("user")) != (b.get("dbname") or b.get("user")):
        return False
    ha, hb = (a.get("host") or "").lower(), (b.get("host") or "").lower()
    return ha == hb or bool(_addresses(ha) & _addresses(hb))


def _addresses(host: str) -> set[str]:
    if not host or host.startswith("/"):
        return {host}
    try:
        return {str(info[4][0]) for info in socket.getaddrinfo(host, None)}
    except (OSError, UnicodeError):
        return set()
