"""SQLite index of the run folders under one output root (``<root>/runs.sqlite``).

The run folders stay the record; the index is for listing and finding them. A run is
added when it starts (status ``running``) and updated when it ends. If a process died
(kill -9, power loss) its row and its ``run.json`` still say running: opening the index
(the store) finds such runs of this host whose recording process is gone and marks them
``killed`` in ``run.json`` too (with the last sample time on disk), so every reader of
the folder agrees with ``rotorbench runs``. ``rebuild`` re-reads every ``run.json``
under the root.

A reader that must not write (the web view) opens it with ``read_only=True``: the file is
opened read-only, nothing is marked, and the listing still reports such runs killed.
A row's folder is a name inside the root (``path_of`` refuses one that leaves it).
"""

from __future__ import annotations

import json
import os
import sqlite3
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from analysis.errors import LogError
from analysis.run_paths import member, read_run_json, samples_path
from bench.errors import RigError
from bench.store.run_summary import RunFilter
from bench.store.sqlite_store import connect, writing

__all__ = ["INDEX_NAME", "Rebuilt", "RunIndex", "RunRow"]

INDEX_NAME = "runs.sqlite"
_SCHEMA = """
CREATE TABLE IF NOT EXISTS runs (
    id TEXT PRIMARY KEY,
    path TEXT NOT NULL,
    rig TEXT,
    components TEXT,
    sequence TEXT,
    started_utc TEXT,
    ended_utc TEXT,
    status TEXT,
    reason TEXT,
    host TEXT,
    pid INTEGER
)
"""


@dataclass(frozen=True)
class RunRow:
    id: str
    path: str
    rig: str
    components: dict[str, Any]
    sequence: str
    started_utc: str
    ended_utc: str | None
    status: str
    reason: str


@dataclass(frozen=True)
class Rebuilt:
    """What ``RunIndex.rebuild`` did: how many runs it indexed, which folders it skipped
    (one line each, naming the file and why)."""

    indexed: int
    skipped: tuple[str, ...] = ()


class RunIndex:
    """A small SQLite table of runs; every call opens its own short connection."""

    def __init__(self, root: Path, *, read_only: bool = False) -> None:
        self.root = Path(root)
        self.path = self.root / INDEX_NAME
        self.read_only = read_only
        if read_only:
            with self._connect() as con:
                _check_table(con, self.path)
            return
        try:
            self.root.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise RigError(f"--out {self.root}: cannot create the run folder "
                           f"({exc.strerror or exc})") from None
        self._connect().close()
        self.mark_killed()

    def mark_killed(self) -> list[str]:
        """Runs of this host still 'running' whose process is gone: write status killed,
        the reason and the last sample time into their ``run.json`` and the index row.
        Returns their ids. A folder that cannot be updated (read-only, gone) is left as it
        is; the listing still reports it killed."""
        import socket

        with self._connect() as con:
            rows = con.execute("SELECT id, path, pid FROM runs WHERE status = 'running' AND "
                               "host = ?", (socket.gethostname(),)).fetchall()
        marked = []
        for rid, rel, pid in rows:
            if not pid or _alive(int(pid)):
                continue
            try:
                run_dir = self.folder(rel)
                meta = read_run_json(run_dir)
                if meta.get("status") != "running" or meta.get("pid") != pid:
                    continue
                samples = samples_path(run_dir, meta)
            except (LogError, RigError):  # gone, damaged, or naming files outside itself
                continue
            last_t, rows_on_disk = _last_sample(samples)
            meta.update(status="killed", reason=f"recording process {pid} is gone (kill -9 or "
                        "power loss); samples up to the last written part",
                        last_sample_t_s=last_t, rows=rows_on_disk,
                        marked_killed_utc=_utc_now())
            try:
                from bench.engine.recorder import atomic_write_json

                atomic_write_json(run_dir / "run.json", meta)
            except OSError:
                continue
            self.upsert(meta, run_dir)
            marked.append(str(rid))
        return marked

    def _connect(self) -> sqlite3.Connection:
        return connect(self.path, _SCHEMA, "run index", _BROKEN, read_only=self.read_only)

    def folder(self, rel: str) -> Path:
        """The run folder of an index row's ``path``: a name inside the root."""
        try:
            return member(self.root, rel, f"{INDEX_NAME} path")
        except LogError as exc:
            raise RigError(str(exc)) from None

    def upsert(self, meta: Mapping[str, Any], run_dir: Path) -> None:
        """Insert or update the row of one run from its ``run.json`` content (a field of
        the wrong type, from a hand-edited file, is stored as text or left empty)."""
        rig, seq = meta.get("rig"), meta.get("sequence")
        row = (
            str(meta.get("id") or run_dir.name),
            os.path.relpath(run_dir, self.root),
            str(rig.get("name", "") if isinstance(rig, Mapping) else rig or ""),
            json.dumps(meta.get("components", {}), default=str),
            str(seq.get("name", "") if isinstance(seq, Mapping) else seq or ""),
            _text(meta.get("started_utc")),
            _text(meta.get("ended_utc")),
            _text(meta.get("status")),
            _text(meta.get("reason")) or "",
            _text(meta.get("host")),
            meta.get("pid") if type(meta.get("pid")) is int else None,
        )
        with writing(self.path, "run index"), self._connect() as con:
            con.execute("INSERT OR REPLACE INTO runs VALUES (?,?,?,?,?,?,?,?,?,?,?)", row)

    def list(self) -> list[RunRow]:
        """Every run, oldest first."""
        return self.select()

    def select(self, where: RunFilter | None = None, *, limit: int | None = None,
               offset: int = 0, newest_first: bool = False) -> list[RunRow]:
        """The runs ``where`` matches (bench aside: it is in run.json), filtered and paged in
        SQL, so a page of 10,000 runs is read at once; every value is a bound parameter."""
        import socket

        clause, params = _where(where)
        order = "started_utc DESC, id DESC" if newest_first else "started_utc"
        sql = f"SELECT {_COLUMNS} FROM runs {clause} ORDER BY {order}"
        if limit is not None:
            sql += " LIMIT ? OFFSET ?"
            params += [int(limit), int(offset)]
        with self._connect() as con:
            rows = con.execute(sql, params).fetchall()
        here = socket.gethostname()
        out = []
        for (rid, path, rig, comps, seq, start, end, status, reason, host, pid) in rows:
            if status == "running" and host == here and pid and not _alive(int(pid)):
                status, reason = "killed", "recording process is gone; samples up to the last part"
            out.append(RunRow(rid, path, rig or "", _components(comps), seq or "",
                              start or "", end, status or "", reason or ""))
        return out

    def count(self, where: RunFilter | None = None) -> int:
        clause, params = _where(where)
        with self._connect() as con:
            return int(con.execute(f"SELECT count(*) FROM runs {clause}", params).fetchone()[0])

    def path_of(self, run_id: str) -> Path | None:
        """The folder of run ``run_id``, None if the index has no such run."""
        with self._connect() as con:
            row = con.execute("SELECT path FROM runs WHERE id = ?", (run_id,)).fetchone()
        return None if row is None else self.folder(row[0])

    def rebuild(self) -> Rebuilt:
        """Re-index every run folder with a ``run.json`` under the root.

        One damaged ``run.json`` (not UTF-8, not JSON, not an object) must not keep the
        others out of the index: it is skipped and named in ``Rebuilt.skipped``."""
        count, skipped = 0, []
        for meta_path in sorted(self.root.glob("*/run.json")):
            try:
                meta = json.loads(meta_path.read_text(encoding="utf-8"))
            except (OSError, ValueError) as exc:  # ValueError: not UTF-8, not JSON
                skipped.append(f"{meta_path}: unreadable run.json ({exc})")
                continue
            if not isinstance(meta, dict):
                skipped.append(f"{meta_path}: expected a JSON object at the top level")
                continue
            self.upsert(meta, meta_path.parent)
            count += 1
        return Rebuilt(count, tuple(skipped))


_BROKEN = "move it away and run `rotorbench runs --rebuild` to index the run folders again"
_COLUMNS = ("id, path, rig, components, sequence, started_utc, ended_utc, status, reason, "
            "host, pid")


def _where(where: RunFilter | None) -> tuple[str, list[Any]]:
    """The SQL ``WHERE`` of a run filter (the bench is in run.json, not in the index; the
    components are JSON: SQLite's json_extract of ``'$.' || key``)."""
    return (where or RunFilter()).sql("?", "json_extract(components, '$.' || ?) = ?",
                                      columns=("status", "sequence"))


def _check_table(con: sqlite3.Connection, path: Path) -> None:
    try:
        con.execute(f"SELECT {_COLUMNS} FROM runs LIMIT 0")
    except sqlite3.DatabaseError as exc:
        raise RigError(f"{path}: not a readable run index ({exc}); {_BROKEN}") from None


def _text(value: Any) -> str | None:
    """A run.json value for a text column: strings as they are, other values as JSON."""
    if value is None or isinstance(value, str):
        return value
    return json.dumps(value, default=str)


def _components(text: str | None) -> dict[str, Any]:
    try:
        value = json.loads(text or "{}")
    except ValueError:
        return {}
    return value if isinstance(value, dict) else {}


def _utc_now() -> str:
    from datetime import UTC, datetime

    return datetime.now(UTC).isoformat(timespec="milliseconds")


def _last_sample(samples: Path) -> tuple[float | None, int]:
    """Largest ``t_s`` and row count of the complete parts on disk (hidden temporary
    parts are skipped by the reader); (None, 0) if nothing is readable."""
    import pyarrow.parquet as pq

    try:
        t = pq.read_table(samples, columns=["t_s"]).column("t_s").to_numpy()
    except Exception:  # no parts, damaged part: the status is what matters here
        return None, 0
    return (float(t.max()) if t.size else None), int(t.size)


def _alive(pid: int) -> bool:
    if pid == os.getpid():
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    # A zombie (killed child not yet reaped) still answers signal 0.
    try:
        with open(f"/proc/{pid}/stat", encoding="ascii") as fh:
            return fh.read().split(")")[-1].split()[0] != "Z"
    except OSError:
        return True
