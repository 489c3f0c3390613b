"""The lab store as commands use it: catalog + data location + spool, from one URL.

``open_lab(url, data=...)`` resolves the data location (``--out s3://...``, else the one
``store init --data`` saved in the catalog) and the spool (``--spool``, else a folder per
user: ``$XDG_DATA_HOME/rotorbench/spool``). ``push`` copies a laptop's folder store
(its runs and constants) into the catalog and skips what is there already.
"""

from __future__ import annotations

import json
import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from bench.errors import RigError
from bench.run.run_ids import check_run_id
from bench.store.lab_catalog import LabCatalog, StoredConstants
from bench.store.lab_publish import Publisher, pending_runs
from bench.store.run_data import DataLocation, row_location
from bench.store.run_summary import RunFilter, RunSummary
from bench.store.store_url import redact
from bench.store.trailing_upload import TrailingUpload

__all__ = ["DATA_SETTING", "LabStore", "PushReport", "SyncReport", "default_spool", "open_lab"]

DATA_SETTING = "data"


def default_cache() -> Path:
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "rotorbench" / "runs"


def default_spool() -> Path:
    base = os.environ.get("XDG_DATA_HOME") or str(Path.home() / ".local" / "share")
    return Path(base) / "rotorbench" / "spool"


@dataclass(frozen=True)
class SyncReport:
    delivered: list[str]
    failed: list[tuple[str, str]]
    waiting_before: int


@dataclass(frozen=True)
class PushReport:
    pushed: list[str]
    skipped: list[str]
    failed: list[tuple[str, str]]
    constants_added: int
    constants_skipped: int


@dataclass
class LabStore:
    catalog: LabCatalog
    location: DataLocation | None  # None: the catalog names none and no --out was given
    spool: Path
    trailing: TrailingUpload | None = None

    @property
    def data(self) -> DataLocation:
        """Where new runs go; asked for only when something is uploaded."""
        if self.location is None:
            raise RigError(f"store {redact(self.catalog.dsn)}: no data location; give --out "
                           "s3://bucket/prefix (or a shared folder), or save one with "
                           "`rotorbench store init URL --data LOCATION`")
        return self.location

    @property
    def publisher(self) -> Publisher:
        return Publisher(self.catalog, self.data)

    # -- the Store interface (bench.store.stores) -----------------------------------------
    def describe(self) -> str:
        where = self.location.uri if self.location else "no data location"
        return f"{redact(self.catalog.dsn)} ({where})"

    def record_root(self) -> Path:
        """Runs are recorded into the spool first, whatever the network does."""
        return self.spool

    def check_can_record(self) -> None:
        """Before anything spins: a reader-only login is refused; a catalog that cannot be
        reached is not (the run is spooled and synced later). Then the parts of the runs
        about to be recorded start trailing to the data location."""
        from bench.store.lab_catalog import CatalogUnavailable

        try:
            self.catalog.check_can_record()
        except CatalogUnavailable:
            return
        if self.location is not None and self.trailing is None:
            self.trailing = TrailingUpload(self.spool, self.location).start()

    def after_run(self, run_dir: Path | None = None) -> str | None:
        """Publish every ended run the spool holds (this one, a map sweep before it); a
        server that is away leaves them spooled, said in one line each."""
        sync = (f"`rotorbench store sync --store {redact(self.catalog.dsn)} --spool "
                f"{self.spool}`")
        try:
            rep = self.sync()
        except RigError as exc:  # the lab is away: the runs wait in the spool
            return (f"spooled: the runs in {self.spool} wait for the lab store ({exc}); "
                    f"deliver them with {sync}")
        lines = [f"stored in {redact(self.catalog.dsn)}: {self.data.run_uri(rid)}"
                 for rid in rep.delivered]
        lines += [f"spooled: {self.spool / rid} waits for the lab store ({why}); deliver it "
                  f"with {sync}" for rid, why in rep.failed]
        return "\n".join(lines) or None

    def list_runs(self, where: RunFilter | None = None, *, limit: int | None = None,
                  offset: int = 0) -> list[RunSummary]:
        return [RunSummary(run_id=r.run_id, bench=r.bench, sequence=r.sequence,
                           status=r.status, samples=r.samples, data=r.data,
                           started_utc=r.started_utc, ended_utc=r.ended_utc, rig=r.rig,
                           reason=r.reason, operator=r.operator, components=r.components)
                for r in self.catalog.list_runs(where, limit=limit, offset=offset)]

    def count_runs(self, where: RunFilter | None = None) -> int:
        return self.catalog.count_runs(where)

    def run_folder(self, run_id: str) -> Path:
        """The run as a local folder: the spool's copy, else a download into the cache
        (from the store's data location: ``row_location`` checks what the row says)."""
        local = self.spool / check_run_id(run_id, f"store {redact(self.catalog.dsn)}: run")
        if (local / "run.json").exists():
            return local
        row = self.catalog.get_run(run_id)
        if row is None:
            raise RigError(f"run {run_id}: not in the store {redact(self.catalog.dsn)}")
        return row_location(run_id, row.data, self.location).download(run_id, default_cache())

    def add_constants(self, rows: Sequence[StoredConstants]) -> int:
        return self.catalog.add_constants(rows)

    def constants(self) -> list[StoredConstants]:
        return self.catalog.constants()

    def sync(self) -> SyncReport:
        """Publish every ended run waiting in the spool; a second call adds nothing."""
        self.data  # noqa: B018 - no data location: said before anything is tried
        sent = self.trailing.stop() if self.trailing is not None else {}
        self.trailing = None
        if (self.spool / "runs.sqlite").exists():  # a run whose process died (kill -9) is
            from bench.store.run_index import RunIndex  # marked killed first, then delivered

            RunIndex(self.spool)
        waiting = pending_runs(self.spool, self.publisher)
        delivered, failed = [], []
        for run_dir in waiting:
            try:
                self.publisher.publish(run_dir, done=sent.get(run_dir.name))
            except RigError as exc:
                failed.append((run_dir.name, str(exc)))
            else:
                delivered.append(run_dir.name)
        return SyncReport(delivered, failed, len(waiting))

    def push(self, folder: Path) -> PushReport:
        """Copy the ended runs and the constants of a folder store into the lab."""
        self.data  # noqa: B018 - no data location: said before anything is tried
        pushed, skipped, failed = [], [], []
        for meta_path in sorted(Path(folder).glob("*/run.json")):
            run_dir = meta_path.parent
            try:
                meta = json.loads(meta_path.read_text(encoding="utf-8"))
            except (OSError, UnicodeDecodeError, ValueError) as exc:
                failed.append((run_dir.name, f"unreadable run.json ({exc})"))
                continue
            run_id = str(meta.get("id") or run_dir.name)
            try:  # checked before the store is asked about it
                check_run_id(run_id, f"{meta_path}: id")
            except RigError as exc:
                failed.append((run_dir.name, str(exc)))
                continue
            if meta.get("status") == "running":
                failed.append((run_id, "still running (or killed: `rotorbench runs` marks it)"))
                continue
            if self.catalog.get_run(run_id) is not None and self.data.has_run(run_id):
                skipped.append(run_id)
                continue
            try:
                self.publisher.publish(run_dir)
            except RigError as exc:
                failed.append((run_id, str(exc)))
            else:
                pushed.append(run_id)
        added, same = self._push_constants(Path(folder))
        return PushReport(pushed, skipped, failed, added, same)

    def _push_constants(self, folder: Path) -> tuple[int, int]:
        from bench.store.constants_store import STORE_NAME, ConstantsStore

        if not (folder / STORE_NAME).exists():
            return 0, 0
        have = {_ckey(c) for c in self.catalog.constants(history=True)}
        rows = ConstantsStore(folder).rows()
        new = []
        for r in rows:
            row = StoredConstants(r.key.motor, r.key.propeller, r.key.esc, r.key.esc_mode,
                                  r.key.battery, r.kind, r.key.catalog, r.run_id,
                                  self.data.run_uri(r.run_id), r.fitted_utc, r.data)
            if _ckey(row) not in have:
                new.append(row)
        if new:
            self.catalog.add_constants(new)
        return len(new), len(rows) - len(new)


def _ckey(c: StoredConstants) -> tuple[str, ...]:
    return (c.motor, c.propeller, c.esc, c.esc_mode, c.battery, c.kind, c.run_id,
            json.dumps(c.data, sort_keys=True))


def open_lab(dsn: str, *, data: str | None = None, spool: Path | None = None) -> LabStore:
    """The lab store at ``dsn``; ``data`` overrides the catalog's data location."""
    from bench.store.lab_catalog import CatalogUnavailable

    catalog = LabCatalog(dsn)
    try:
        where = data or catalog.setting(DATA_SETTING)
    except CatalogUnavailable:  # a bench still records (into the spool) with the lab away
        where = None
    return LabStore(catalog, DataLocation(where) if where else None,
                    Path(spool) if spool else default_spool())
