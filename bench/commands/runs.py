"""``rotorbench runs``: list the recorded runs from the SQLite index of an output root."""

from __future__ import annotations

import argparse
import shutil
from pathlib import Path

from rich.console import Console
from rich.table import Table

from bench.commands._output import check_writable
from bench.run_index import INDEX_NAME, RunIndex


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser("runs", help="list recorded runs (from <out>/runs.sqlite)")
    p.add_argument("--out", type=Path, default=Path("runs"),
                   help="output root of the runs (default: ./runs)")
    p.add_argument("--rebuild", action="store_true",
                   help="re-index every run folder's run.json first")
    p.set_defaults(func=handler)


def handler(args: argparse.Namespace) -> int:
    if not (args.out / INDEX_NAME).exists() and not args.rebuild:
        print(f"no runs recorded under {args.out} (no {INDEX_NAME})")
        return 0
    if args.rebuild:
        check_writable(args.out, "--out", folder=True)
    index = RunIndex(args.out)
    if args.rebuild:
        index.rebuild()
    rows = index.list()
    table = Table(title=f"runs in {args.out}")
    for col in ("id", "sequence", "rig", "esc mode", "started (UTC)", "status", "reason"):
        table.add_column(col, overflow="fold")
    for r in rows:
        table.add_row(r.id, r.sequence, r.rig, str(r.components.get("esc_mode", "")),
                      r.started_utc[:19], r.status, r.reason)
    Console(width=shutil.get_terminal_size((160, 24)).columns).print(table)
    return 0
