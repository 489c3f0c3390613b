"""One ``Store`` interface for runs and constants, with its two implementations.

* ``FolderStore``: the embedded default, a folder of run folders with ``runs.sqlite`` and
  ``constants.sqlite`` beside them (``bench.store.run_index``, ``bench.store.constants_store``).
* ``LabStore`` (``bench.store.lab_store``): the PostgreSQL catalog with the run folders in
  a shared folder or an S3 bucket, runs recorded into a local spool first.

Commands ask ``open_store(--store)`` for one and use only what is here: where a new run
is recorded, what happens after it, the list of runs, a run as a local folder, and the
constants. The web view and the optimizer's ``--measured`` read through the same calls.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, Protocol

from bench.errors import RigError
from bench.store.run_summary import RunFilter, RunSummary

__all__ = ["FolderStore", "RunSummary", "Store", "open_store"]


class Store(Protocol):
    """What a command may ask of a store."""

    def describe(self) -> str: ...
    def record_root(self) -> Path: ...
    def check_can_record(self) -> None: ...
    def after_run(self, run_dir: Path | None = None) -> str | None: ...
    def list_runs(self, where: RunFilter | None = None, *, limit: int | None = None,
                  offset: int = 0) -> list[RunSummary]: ...
    def count_runs(self, where: RunFilter | None = None) -> int: ...
    def run_folder(self, run_id: str) -> Path: ...
    def add_constants(self, rows: Sequence[Any]) -> int: ...
    def constants(self, *, history: bool = False) -> list[Any]: ...


@dataclass(frozen=True)
class FolderStore:
    """The embedded store at ``root`` (today's ``--out`` folder). ``read_only``: a reader
    that must not write (the web view) opens the index read-only; a run whose process
    died is listed as killed without marking it in its files."""

    root: Path
    read_only: bool = False

    @property
    def path(self) -> Path:
        """The constants store's file (what the constants table is titled with)."""
        from bench.store.constants_store import STORE_NAME

        return self.root / STORE_NAME

    def describe(self) -> str:
        return str(self.root)

    def record_root(self) -> Path:
        return self.root

    def check_can_record(self) -> None:
        """Nothing to ask: the recording commands check ``--out`` is writable."""

    def after_run(self, run_dir: Path | None = None) -> str | None:
        return None  # recorded in place, indexed as it ran

    def list_runs(self, where: RunFilter | None = None, *, limit: int | None = None,
                  offset: int = 0) -> list[RunSummary]:
        if where is not None and where.bench is not None:  # the bench is in run.json
            runs = [r for r in map(self._complete, self._query(where)) if where.matches(r)]
            end = None if limit is None else offset + limit
            return runs[offset:end]
        return [self._complete(r) for r in self._query(where, limit, offset)]

    def count_runs(self, where: RunFilter | None = None) -> int:
        if where is not None and where.bench is not None:
            return len(self.list_runs(where))
        return self._query(where, count=True)  # type: ignore[return-value]

    def _query(self, where: RunFilter | None, limit: int | None = None, offset: int = 0,
               count: bool = False) -> Any:
        """Index rows newest first, filtered and paged by the index (``RunIndex.select``);
        opening the index first marks runs whose recording process died."""
        from bench.store.run_index import INDEX_NAME, RunIndex

        if not (self.root / INDEX_NAME).exists():
            return 0 if count else []
        index = RunIndex(self.root, read_only=self.read_only)
        if count:
            return index.count(where)
        return [RunSummary(run_id=r.id, bench=r.rig, sequence=r.sequence, status=r.status,
                           samples=0, data=_folder_text(index, r.path),
                           started_utc=r.started_utc or None, ended_utc=r.ended_utc, rig=r.rig,
                           reason=r.reason, components=r.components)
                for r in index.select(where, limit=limit, offset=offset, newest_first=True)]

    def _complete(self, r: RunSummary) -> RunSummary:
        """The summary with what only run.json holds: bench, operator, sample count."""
        if r.samples or r.operator or not r.data:
            return r
        meta = _read_meta(Path(r.data))
        rows = meta.get("rows")
        return replace(r, bench=_bench(meta, r.rig),
                       samples=rows if type(rows) is int and rows >= 0 else 0,
                       operator=str(meta.get("operator") or ""),
                       data=str(Path(r.data).resolve()))

    def run_folder(self, run_id: str) -> Path:
        from bench.engine.run_ids import check_run_id
        from bench.store.run_index import INDEX_NAME, RunIndex

        check_run_id(run_id, f"store {self.root}: run")
        folder = RunIndex(self.root, read_only=self.read_only).path_of(run_id) \
            if (self.root / INDEX_NAME).exists() else None
        if folder is None:
            raise RigError(f"run {run_id}: not in the store {self.root}")
        return folder

    def add_constants(self, rows: Sequence[Any]) -> int:
        from bench.store.constants_store import ActuatorKey, ConstantsStore

        store = ConstantsStore(self.root)
        for r in rows:
            store.put(ActuatorKey(r.motor, r.propeller, r.esc, r.esc_mode, r.battery,
                                  r.catalog), r.kind, r.run_id, r.run_path, r.data)
        return len(rows)

    def constants(self, *, history: bool = False) -> list[Any]:
        """The stored constants; ``history`` changes nothing here: a folder keeps one row
        per actuator and kind (a newer fit replaces the older), its history is its rows."""
        from bench.store.constants_store import ConstantsStore
        from bench.store.lab_catalog import StoredConstants

        return [StoredConstants(r.key.motor, r.key.propeller, r.key.esc, r.key.esc_mode,
                                r.key.battery, r.kind, r.key.catalog, r.run_id, r.run_path,
                                r.fitted_utc, r.data) for r in ConstantsStore(self.root).rows()]


def _read_meta(run_dir: Path) -> Mapping[str, Any]:
    """run.json for the listing; a damaged one lists the run with what the index has."""
    from analysis.errors import LogError
    from analysis.run_paths import read_run_json

    try:
        return read_run_json(run_dir)
    except LogError:
        return {}


def _folder_text(index: Any, rel: str) -> str:
    """An index row's run folder; empty for a row whose folder would leave the store."""
    try:
        return str(index.folder(rel))
    except RigError:
        return ""


def _bench(meta: Mapping[str, Any], rig: str) -> str:
    from bench.store.lab_publish import bench_name

    return bench_name({**meta, "rig": meta.get("rig") or rig}) if meta else rig


def open_store(text: str | Path | None, *, data: str | None = None,
               spool: Path | None = None, default: str = "runs") -> Store:
    """The store ``--store`` names (``$ROTORBENCH_STORE``, else ``default``)."""
    from bench.store.store_url import parse_store

    url = parse_store(text, default=default)
    if url.folder is not None:
        return FolderStore(url.folder)
    from bench.store.lab_store import open_lab

    assert url.dsn is not None
    return open_lab(url.dsn, data=data, spool=spool)
