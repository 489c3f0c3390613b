"""``rotorbench runs``: list the recorded runs of a store (the folder's SQLite index, or
the lab catalog with ``--store postgresql://...``), as a table or ``--json``."""

from __future__ import annotations

import argparse
import json
import shutil
import sys
from pathlib import Path

from rich.console import Console
from rich.table import Table

from bench.cli_args.store_args import add_store_args, store_from_args
from bench.errors import RigError
from bench.paths.outputs import check_folder_to_read, check_writable
from bench.store.run_index import INDEX_NAME, RunIndex
from bench.store.stores import Store


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser("runs", help="list recorded runs (from <out>/runs.sqlite)")
    p.add_argument("--out", type=Path, default=Path("runs"),
                   help="output root of the runs (default: ./runs)")
    p.add_argument("--rebuild", action="store_true",
                   help="re-index every run folder's run.json first (folder stores)")
    p.add_argument("--json", action="store_true",
                   help="print the runs as JSON (run_id, bench, sequence, status, samples, "
                        "data, ...), newest first")
    p.add_argument("--bench", default=None, help="only the runs of this bench")
    p.add_argument("--status", default=None, help="only runs with this status (e.g. trip)")
    p.add_argument("--since", default=None, metavar="DATE",
                   help="only runs started at or after DATE (YYYY-MM-DD or ISO time, UTC)")
    p.add_argument("--until", default=None, metavar="DATE",
                   help="only runs started before DATE (YYYY-MM-DD or ISO time, UTC)")
    p.add_argument("--limit", type=int, default=None, help="at most this many runs")
    add_store_args(p)
    p.set_defaults(func=handler)


def drops_text(run_dir: Path) -> str:
    """``0``, ``! 12 (gap 0.040 s)`` for a run with drops (``, ! 3 link errors`` when frames
    were lost on a device's link), ``-`` for a record without the
    count (older runs, killed runs, a damaged ``run.json``); from the run's ``run.json``."""
    from analysis.errors import LogError
    from analysis.run_paths import read_run_json

    try:
        meta = read_run_json(run_dir)
    except LogError:
        return "-"
    n, gap, link = (meta.get(k) for k in ("dropped_samples", "longest_gap_s", "link_errors"))
    if type(n) is not int or not isinstance(gap, int | float | None) \
            or not isinstance(link, int | None):
        return "-"
    text = f"! {n} (gap {gap or 0:.3f} s)" if n else "0"
    return f"{text}, ! {link} link errors" if link else text


def _lab_listing(args: argparse.Namespace, store: Store) -> int:
    from bench.store.run_summary import RunFilter

    if args.rebuild:
        raise RigError("--rebuild re-indexes a folder store; the lab catalog is indexed as "
                       "runs are published (`rotorbench store sync` delivers waiting ones)")
    where = RunFilter(bench=args.bench, status=args.status, since=args.since,
                      until=args.until)
    runs = store.list_runs(where, limit=args.limit)
    if args.json:
        print(json.dumps([r.as_dict() for r in runs], indent=1))
        return 0
    table = Table(title=f"runs in {store.describe()}")
    for col in ("id", "bench", "sequence", "esc mode", "started (UTC)", "status", "samples",
                "reason"):
        table.add_column(col, overflow="fold")
    for r in runs:
        table.add_row(r.run_id, r.bench, r.sequence, str(r.components.get("esc_mode", "")),
                      (r.started_utc or "")[:19], r.status, str(r.samples), r.reason)
    Console(width=shutil.get_terminal_size((160, 24)).columns).print(table)
    return 0


def handler(args: argparse.Namespace) -> int:
    from bench.store.run_summary import utc_bound

    if args.limit is not None and args.limit < 1:
        raise RigError(f"--limit {args.limit}: expected at least 1")
    for name in ("since", "until"):  # checked before any store is opened
        if getattr(args, name) is not None:
            utc_bound(getattr(args, name), f"--{name}")
    store = store_from_args(args)
    if not hasattr(store, "root"):
        return _lab_listing(args, store)
    args.out = store.root
    check_folder_to_read(args.out)
    if args.json or args.bench or args.status or args.limit or args.since or args.until:
        if args.rebuild:
            check_writable(args.out, "--out", folder=True)
            for line in RunIndex(args.out).rebuild().skipped:
                print(f"rotorbench: skipped {line}", file=sys.stderr)
        return _lab_listing(argparse.Namespace(**{**vars(args), "rebuild": False}), store)
    if not (args.out / INDEX_NAME).exists() and not args.rebuild:
        print(f"no runs recorded under {args.out} (no {INDEX_NAME})")
        return 0
    if args.rebuild:
        check_writable(args.out, "--out", folder=True)
    index = RunIndex(args.out)
    skipped: tuple[str, ...] = ()
    if args.rebuild:
        skipped = index.rebuild().skipped
    rows = index.list()
    table = Table(title=f"runs in {args.out}")
    for col in ("id", "sequence", "rig", "esc mode", "started (UTC)", "status", "drops",
                "reason"):
        table.add_column(col, overflow="fold")
    for r in rows:
        table.add_row(r.id, r.sequence, r.rig, str(r.components.get("esc_mode", "")),
                      r.started_utc[:19], r.status, drops_text(args.out / r.path), r.reason)
    Console(width=shutil.get_terminal_size((160, 24)).columns).print(table)
    for line in skipped:  # after the table, so the last thing read is what is missing
        print(f"rotorbench: skipped {line}", file=sys.stderr)
    return 0
