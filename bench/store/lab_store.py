"""The lab store as commands use it: catalog + data location + spool, from one URL.

``open_lab(url, data=...)`` resolves the data location (``--out s3://...``, else the one
``store init --data`` saved in the catalog) and the spool (``--spool``, else a folder per
user: ``$XDG_DATA_HOME/rotorbench/spool``). A recording command writes where its runs go
into the spool's ledger before anything spins (``bench.store.spool_destinations``), and
every delivery (after the run, ``store sync``) takes each run there and only there.
``push`` copies a laptop's folder store (its runs and constants) into the catalog and
skips what is there already. Every command that writes checks the login may record
before it touches the data location.
"""

from __future__ import annotations

import atexit
import json
import logging
import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from bench.engine.run_ids import check_run_id
from bench.errors import RigError
from bench.store.lab_catalog import (
    CatalogIdentity,
    CatalogUnavailable,
    LabCatalog,
    StoredConstants,
)
from bench.store.lab_publish import Publisher, pending_runs, read_meta
from bench.store.run_data import DataLocation, row_location
from bench.store.run_summary import RunFilter, RunSummary
from bench.store.spool_destinations import Destination, Ledger, same_address
from bench.store.store_url import redact, show_params
from bench.store.trailing_upload import TrailingUpload

_log = logging.getLogger(__name__)

__all__ = ["DATA_SETTING", "LabStore", "PushReport", "SyncReport", "default_spool", "open_lab",
           "sync_every_destination", "where_going"]

DATA_SETTING = "data"


def default_cache() -> Path:
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "rotorbench" / "runs"


def default_spool() -> Path:
    base = os.environ.get("XDG_DATA_HOME") or str(Path.home() / ".local" / "share")
    return Path(base) / "rotorbench" / "spool"


@dataclass(frozen=True)
class SyncReport:
    """``delivered``: (run id, data URI); ``failed``: (run folder, why) of this catalog's
    runs and of unreadable ones; ``elsewhere``: (run folder, where it goes) of the runs
    going to another catalog, left alone."""

    delivered: list[tuple[str, str]]
    failed: list[tuple[str, str]]
    elsewhere: list[tuple[str, str]]
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
    away: str | None = None  # why the catalog could not be asked for its data location
    _told: set[str] = field(default_factory=set)  # run folders a note was printed for
    #: where the at-exit note of runs left in the spool goes: the recording command's
    #: stderr (``bench.cli_args.store_args.recording_store``), else the log
    exit_notice: Callable[[str], None] = _log.warning

    @property
    def data(self) -> DataLocation:
        """Where new runs go; asked for only when something is uploaded."""
        if self.location is None:
            if self.away is not None:
                raise CatalogUnavailable(self.away)
            raise RigError(f"store {redact(self.catalog.dsn)}: no data location; give --out "
                           "s3://bucket/prefix (or a shared folder), or save one with "
                           "`rotorbench store init URL --data LOCATION`")
        return self.location

    # -- the Store interface (bench.store.stores) -----------------------------------------
    def describe(self) -> str:
        where = self.location.uri if self.location else "no data location"
        return f"{redact(self.catalog.dsn)} ({where})"

    def record_root(self) -> Path:
        """Runs are recorded into the spool first, whatever the network does."""
        return self.spool

    def check_can_record(self) -> None:
        """Before anything spins: a reader-only login is refused; a catalog that cannot be
        reached is not (the run is spooled and synced later). Where this command's runs go
        is written into the spool's ledger; then the parts of the runs about to be
        recorded start trailing to the data location, each run announced as it starts."""
        try:
            ident: CatalogIdentity | None = self.catalog.check_can_record()
        except CatalogUnavailable:
            ident = None
        Ledger(self.spool).record(catalog_id=ident.catalog_id if ident else None,
                                  params=self.catalog.params,
                                  data=self.location.uri if self.location else None)
        if ident is not None and self.location is not None and self.trailing is None:
            announce = Publisher(self.catalog, self.location, ident.catalog_id).announce
            self.trailing = TrailingUpload(self.spool, self.location, announce=announce).start()
        atexit.register(self._at_exit)

    def _sync_hint(self) -> str:
        return f"`rotorbench store sync --store {redact(self.catalog.dsn)} --spool {self.spool}`"

    def after_run(self, run_dir: Path | None = None) -> str | None:
        """Publish every ended run the spool holds for this catalog (this one, a map sweep
        before it); a server that is away leaves them spooled, said in one line each."""
        try:
            rep = self.sync()
        except RigError as exc:  # the lab is away: the runs wait in the spool
            self._stop_trailing()
            self._told.update(d.name for d in self._left_by_me())
            return (f"spooled: the runs in {self.spool} wait for the lab store ({exc}); "
                    f"deliver them with {self._sync_hint()}")
        lines = [f"stored in {redact(self.catalog.dsn)}: {uri}" for _, uri in rep.delivered]
        lines += [f"spooled: {self.spool / name} waits for the lab store ({why}); deliver it "
                  f"with {self._sync_hint()}" for name, why in rep.failed]
        self._told.update(name for name, _ in rep.failed)
        return "\n".join(lines) or None

    def _left_by_me(self) -> list[Path]:
        return [p.run_dir for p in pending_runs(self.spool)
                if p.meta is not None and p.meta.get("pid") == os.getpid()]

    def _at_exit(self) -> None:
        """At interpreter exit: stop the trailing upload (no pyarrow work may be in flight
        when Python shuts down), and name the runs this process left in the spool without
        a word, e.g. after a full disk or SIGTERM ended the command before its publish."""
        self._stop_trailing()
        try:
            left = [d for d in self._left_by_me() if d.name not in self._told]
        except OSError:
            return
        for run_dir in left:
            self.exit_notice(f"spooled: {run_dir} waits for the lab store; deliver it "
                             f"with {self._sync_hint()}")

    def _stop_trailing(self) -> dict[str, set[str]]:
        sent = self.trailing.stop() if self.trailing is not None else {}
        self.trailing = None
        return sent

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

    def constants(self, *, history: bool = False) -> list[StoredConstants]:
        """The newest constants per actuator and kind, or every row ever added."""
        return self.catalog.constants(history=history)

    def sync(self, *, explicit: bool = False) -> SyncReport:
        """Deliver the ended runs waiting in the spool whose destination is this catalog;
        a second call adds nothing. ``explicit`` (``store sync --store URL``): also the
        runs no lab command recorded a destination for. The login's right to record is
        checked first, before anything is uploaded."""
        ident = self.catalog.check_can_record()
        sent = self._stop_trailing()
        if (self.spool / "runs.sqlite").exists():  # a run whose process died (kill -9) is
            from bench.store.run_index import RunIndex  # marked killed first, then delivered

            RunIndex(self.spool)
        ledger = Ledger(self.spool)
        delivered: list[tuple[str, str]] = []
        failed: list[tuple[str, str]] = []
        elsewhere: list[tuple[str, str]] = []
        for item in pending_runs(self.spool):
            name = item.run_dir.name
            if item.meta is None:
                failed.append((name, str(item.unreadable)))
                continue
            dest = ledger.of(item.meta)
            if dest is not None and dest.catalog_id is None and self._is_here(dest, ident):
                dest = ledger.resolve(dest, ident.catalog_id)
            if dest is None and not explicit:
                elsewhere.append((name, "no destination recorded: `store sync --store URL` "
                                  "names its catalog"))
                continue
            if dest is not None and dest.catalog_id != ident.catalog_id:
                elsewhere.append((name, where_going(dest)))
                continue
            try:
                data = DataLocation(dest.data) if dest is not None and dest.data else self.data
                uri = Publisher(self.catalog, data, ident.catalog_id).publish(
                    item.run_dir, done=sent.get(name))
            except RigError as exc:
                failed.append((name, str(exc)))
            else:
                delivered.append((name, uri))
        return SyncReport(delivered, failed, elsewhere, len(delivered) + len(failed))

    def _is_here(self, dest: Destination, ident: CatalogIdentity) -> bool:
        """A destination recorded while its catalog was away names this one: the same
        database on the same server as this store's URL or where its connection went."""
        return same_address(dest.params, self.catalog.params) or \
            same_address(dest.params, ident.address)

    def push(self, folder: Path) -> PushReport:
        """Copy the ended runs and the constants of a folder store into the lab; a login
        that may not record is refused before the data location is touched."""
        ident = self.catalog.check_can_record()
        publisher = Publisher(self.catalog, self.data, ident.catalog_id)
        pushed, skipped, failed = [], [], []
        for meta_path in sorted(Path(folder).glob("*/run.json")):
            run_dir = meta_path.parent
            try:
                meta = read_meta(run_dir)
            except RigError as exc:
                failed.append((run_dir.name, str(exc)))
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
                publisher.publish(run_dir)
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


def where_going(dest: Destination) -> str:
    """A destination as it may be printed (its parameters hold no secret)."""
    catalog = f"catalog {dest.catalog_id}" if dest.catalog_id else "a catalog not reached yet"
    return f"goes to {catalog} at {show_params(dest.params)}"


def sync_every_destination(spool: Path) -> list[tuple[str, SyncReport | RigError]]:
    """``store sync`` without a catalog named: each waiting run to the catalog its command
    named, connecting with the secret-free parameters the ledger kept (libpq takes the
    password from PGPASSWORD, ~/.pgpass or the service file). Per catalog: (the catalog as
    it may be printed, its report or why it could not be reached)."""
    from bench.store.store_url import conninfo_text

    ledger = Ledger(spool)
    targets: dict[str, str] = {}
    for item in pending_runs(spool):
        dest = ledger.of(item.meta) if item.meta is not None else None
        if dest is not None:
            targets.setdefault(conninfo_text(dest.params), show_params(dest.params))
    out: list[tuple[str, SyncReport | RigError]] = []
    for text, shown in targets.items():
        try:
            out.append((shown, open_lab(text, spool=spool).sync()))
        except RigError as exc:
            out.append((shown, exc))
    return out


def open_lab(dsn: str, *, data: str | None = None, spool: Path | None = None) -> LabStore:
    """The lab store at ``dsn``; ``data`` overrides the catalog's data location."""
    catalog = LabCatalog(dsn)
    away = None
    try:
        where = data or catalog.setting(DATA_SETTING)
    except CatalogUnavailable as exc:  # a bench still records (into the spool) with the
        where, away = None, str(exc)  # lab away; a sync says the catalog is unreachable
    return LabStore(catalog, DataLocation(where) if where else None,
                    Path(spool) if spool else default_spool(), away=away)
