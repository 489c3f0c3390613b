"""``rotorbench store``: set up the lab catalog, deliver spooled runs, push a laptop's runs.

* ``store init URL [--data LOCATION]`` creates or upgrades the PostgreSQL schema and the
  ``rotorbench_writer`` / ``rotorbench_reader`` roles; running it twice changes nothing.
* ``store sync [--store URL] [--spool DIR]`` delivers the runs that waited in the spool
  while the database or the object store was away, each to the catalog and data location
  its recording command named (``--store``: only that catalog's); running it twice adds
  nothing.
* ``store push DIR --store URL [--out LOCATION]`` copies a folder store's runs and
  constants into the catalog; runs already there are skipped and said so.

Passwords come from the URL, ``PGPASSWORD``, ``~/.pgpass`` or a libpq service and are never
printed: every URL shown is redacted.
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path

from bench.errors import RigError
from bench.paths.outputs import check_folder_to_read
from bench.store.store_url import STORE_ENV, parse_store, redact


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser("store", help="lab catalog: init, sync spooled runs, push runs",
                              description=__doc__.split("\n\n")[1] if __doc__ else None,
                              formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = p.add_subparsers(dest="action", metavar="{init,sync,push}", required=True)
    init = sub.add_parser("init", help="create or upgrade the catalog schema and roles")
    init.add_argument("url", metavar="URL", help="postgresql://user@host/db (libpq options "
                      "such as ?sslmode=require pass through)")
    init.add_argument("--data", metavar="LOCATION",
                      help="default data location of the lab: s3://bucket/prefix or a "
                           "shared folder")
    init.set_defaults(func=_init)
    sync = sub.add_parser("sync", help="deliver the runs waiting in the spool, each where it "
                          "was going")
    sync.add_argument("--store", metavar="URL", help="only the runs going to this catalog "
                      "(default: $ROTORBENCH_STORE, else every run to its own catalog)")
    sync.add_argument("--spool", type=Path, help="the spool folder (default: per user, "
                      "~/.local/share/rotorbench/spool)")
    sync.add_argument("--out", metavar="LOCATION", help="data location of runs recorded "
                      "without one (default: the catalog's, from store init --data)")
    sync.set_defaults(func=_sync)
    push = sub.add_parser("push", help="copy a folder store's runs and constants into the "
                          "catalog")
    push.add_argument("folder", type=Path, metavar="DIR", help="a folder store (e.g. ./runs)")
    _store_arg(push)
    push.add_argument("--out", metavar="LOCATION", help="data location (default: the "
                      "catalog's, from store init --data)")
    push.set_defaults(func=_push)


def _store_arg(p: argparse.ArgumentParser) -> None:
    p.add_argument("--store", metavar="URL", help="the lab catalog, postgresql://... "
                   "(default: $ROTORBENCH_STORE)")


def _lab_url(args: argparse.Namespace) -> str:
    url = parse_store(args.store, default="")
    if not url.is_lab:
        raise RigError("store: give the lab catalog with --store postgresql://... or "
                       "ROTORBENCH_STORE")
    assert url.dsn is not None
    return url.dsn


def _init(args: argparse.Namespace) -> int:
    from bench.store.lab_catalog import LabCatalog
    from bench.store.lab_store import DATA_SETTING
    from bench.store.run_data import DataLocation

    url = parse_store(args.url)
    if not url.is_lab:
        raise RigError(f"store init {redact(args.url)}: needs a postgresql:// URL (a folder "
                       "store needs no init)")
    assert url.dsn is not None
    if args.data:
        DataLocation(args.data)  # no credentials in it: refused before the catalog is touched
    cat = LabCatalog(url.dsn)
    before, after = cat.init()
    if args.data:
        cat.set_setting(DATA_SETTING, args.data)
    what = ("created" if before == 0 else
            f"upgraded from {before}" if before < after else "already current")
    print(f"store {url.shown()}: schema version {after} ({what}); roles rotorbench_writer "
          "and rotorbench_reader ready")
    if args.data:
        print(f"data location: {args.data}")
    return 0


def _sync(args: argparse.Namespace) -> int:
    from bench.store.lab_store import default_spool, open_lab
    from bench.store.run_data import DataLocation

    named = bool(args.store or os.environ.get(STORE_ENV))
    dsn = _lab_url(args) if named else None  # a wrong --store or --out is said first
    if args.out:
        DataLocation(args.out)
    spool = Path(args.spool) if args.spool else default_spool()
    if not spool.exists():
        print(f"nothing to sync: no spool at {spool}")
        return 0
    if dsn is None:
        return _sync_every_destination(spool)
    lab = open_lab(dsn, data=args.out, spool=spool)
    rep = lab.sync(explicit=True)
    for name, why in rep.failed:
        print(f"still spooled: {name}: {why}")
    if rep.elsewhere:
        print(f"left in the spool: {len(rep.elsewhere)} runs going to other catalogs; "
              f"`rotorbench store sync --spool {spool}` (no --store) delivers each to its own")
    print(f"synced {len(rep.delivered)} of {rep.waiting_before} waiting runs from {spool} "
          f"to {redact(lab.catalog.dsn)}")
    return 2 if rep.failed else 0


def _sync_every_destination(spool: Path) -> int:
    from bench.store.lab_publish import pending_runs
    from bench.store.lab_store import SyncReport, sync_every_destination
    from bench.store.spool_destinations import Ledger

    why: dict[str, str] = {}
    for shown, rep in sync_every_destination(spool):
        if isinstance(rep, SyncReport):
            why.update(rep.failed)
            print(f"synced {len(rep.delivered)} of {rep.waiting_before} waiting runs from "
                  f"{spool} to {shown}")
        else:
            print(f"not synced to {shown}: {rep}")
    ledger = Ledger(spool)
    left = pending_runs(spool)
    for item in left:
        name = item.run_dir.name
        if item.meta is None:
            reason = str(item.unreadable)
        elif ledger.of(item.meta) is None:
            reason = "no destination recorded; `store sync --store URL` names its catalog"
        else:
            reason = why.get(name, "its catalog was not reached (said above)")
        print(f"still spooled: {name}: {reason}")
    return 2 if left else 0


def _push(args: argparse.Namespace) -> int:
    from bench.store.lab_store import open_lab

    check_folder_to_read(args.folder, "DIR")
    lab = open_lab(_lab_url(args), data=args.out)
    rep = lab.push(args.folder)
    for run_id in rep.skipped:
        print(f"skipped {run_id}: already in the catalog")
    for run_id, why in rep.failed:
        print(f"not pushed {run_id}: {why}")
    print(f"pushed {len(rep.pushed)} runs ({len(rep.skipped)} already there), "
          f"{rep.constants_added} constants rows ({rep.constants_skipped} already there) to "
          f"{redact(lab.catalog.dsn)} ({lab.data.uri})")
    return 2 if rep.failed else 0
