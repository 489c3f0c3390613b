"""``rotorbench import FILE [--format F] --out DIR``: another bench's log as a run folder.

The format is read from the header unless ``--format`` forces it (``--map`` implies csv);
the output line says which was taken and how. Flight logs (Betaflight/INAV blackbox, PX4
ULog, ArduPilot DataFlash; ``analysis.flightlogs``) become runs of kind ``flight``; a
blackbox file holding several logs gives one run each (``DIR``, ``DIR-2``, ...) unless
``--log N`` picks one.

Parsing lives in ``analysis.importers``; this is the glue that writes the run folder with
``bench.engine.recorder.RunRecorder`` into a temporary folder beside ``DIR`` and renames it into
place, so an interrupted import leaves nothing half-written under the final name.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from analysis.flightlogs import FLIGHT_FORMATS
from bench.errors import RigError
from bench.store.imported_run import write_run

COMMAND = "import"


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        COMMAND, help="import a thrust-stand log (RCbenchmark, ESC32, any CSV) or a flight "
                      "log (blackbox, ULog, DataFlash) as a run",
        description="Reads another bench's log and writes a run folder with the run's column "
                    "names and SI units (units from the file's column names). A flight log "
                    "(Betaflight/INAV blackbox, PX4 ULog, ArduPilot DataFlash) becomes a run of "
                    "kind flight (docs/flight-logs.md). A CSV whose "
                    "columns already carry run names (t_s, throttle_us, thrust_n, rpm, ...) "
                    "needs no --map. The format is detected from the header; --format "
                    "forces one, --map implies csv.")
    p.add_argument("file", type=Path, help="log file")
    p.add_argument("--format", dest="fmt",
                   choices=("rcbenchmark", "esc32", "csv", *FLIGHT_FORMATS),
                   default=None, help="force the format (default: detected from the header)")
    p.add_argument("--map", dest="mapping", action="append", default=[],
                   metavar="RUNCOL=FILECOL", help="csv only: take a run column from a file "
                                                  "column (repeatable)")
    p.add_argument("--log", dest="log_index", type=int, default=None, metavar="N",
                   help="flight logs: import only the N-th log of the file (1 = first)")
    p.add_argument("--max-rows", type=int, default=None, metavar="N",
                   help="flight logs: keep at most N rows per log (default 20,000,000)")
    p.add_argument("--out", type=Path, required=True, help="run folder to create")
    p.set_defaults(func=handler)


def parse_mapping(items: list[str]) -> dict[str, str]:
    out: dict[str, str] = {}
    for item in items:
        run_col, sep, file_col = item.partition("=")
        if not sep or not run_col or not file_col:
            raise RigError(f"--map {item!r}: expected RUNCOL=FILECOL")
        if run_col.strip() in out:
            raise RigError(f"--map {item!r}: {run_col.strip()} is mapped twice "
                           f"(first to {out[run_col.strip()]!r})")
        out[run_col.strip()] = file_col.strip()
    return out


def handler(args: argparse.Namespace) -> int:
    from analysis.importers import JITTER_MAX_PERIODS, detect_format, import_log
    from bench.engine.run_ids import check_run_id
    from bench.paths.outputs import check_writable

    if args.out.exists():
        raise RigError(f"--out {args.out}: already exists (choose a new run folder)")
    check_run_id(args.out.name, f"--out {args.out}: the folder's name (the run's id)")
    check_writable(args.out, "--out", folder=True, beside=True)
    mapping = parse_mapping(args.mapping) or None
    if args.fmt in FLIGHT_FORMATS or (not args.fmt and not mapping):
        from analysis.flightlogs import detect_flight_format

        flight = args.fmt or detect_flight_format(args.file)
        if flight:
            if mapping:
                raise RigError(f"--map applies to --format csv only (the {flight} fields "
                               "are known)")
            return import_flight(args, flight, "--format" if args.fmt else
                                 "detected from its first bytes")
    if args.log_index is not None or args.max_rows is not None:
        raise RigError("--log and --max-rows apply to flight logs only")
    if args.fmt:
        fmt, how = args.fmt, "--format"
    elif mapping:
        fmt, how = "csv", "--map"
    else:
        fmt, how = detect_format(args.file), "detected from the header"
    samples, meta = import_log(args.file, fmt, mapping)
    meta["format_taken"] = how
    meta = {"kind": "import", "components": {}, "import": meta}
    out = write_run(args.out, samples, meta)
    cols = ", ".join(c for c in samples.columns)
    dialect = meta["import"].get("csv_dialect")
    how = f"{how}, {dialect}" if dialect else how
    print(f"{out}: imported {len(samples)} rows from {args.file} ({fmt}, {how}); "
          f"columns {cols}")
    order = meta["import"].get("time_order") or {}
    if order.get("reordered_rows"):
        print(f"time order: {order['reordered_rows']} rows reordered where the time stepped "
              f"back ({order['time_steps_back']} places, at most "
              f"{order['max_step_back_s'] * 1e3:.3g} ms; bound {JITTER_MAX_PERIODS:g} sample "
              f"periods = {order['jitter_bound_s'] * 1e3:.3g} ms); recorded in run.json "
              "import.time_order")
    cut = meta["import"].get("cut_last_line")
    if cut:
        print(f"dropped line {cut['line']} ({cut['text'][:40]!r}): the file ends inside it "
              "(no line break; the logger stopped mid-line?); recorded in run.json "
              "import.cut_last_line")
    return 0


def import_flight(args: argparse.Namespace, fmt: str, how: str) -> int:
    """Each log of a flight-log file as a run of kind ``flight``."""
    import pandas as pd

    from analysis.flightlogs import read_flight_log
    from bench.engine.run_ids import check_run_id

    for flag, value in (("--log", args.log_index), ("--max-rows", args.max_rows)):
        if value is not None and value < 1:
            raise RigError(f"{flag} {value}: expected a whole number of at least 1")
    logs = read_flight_log(args.file, fmt, max_rows=args.max_rows)
    picked = list(enumerate(logs, start=1))
    if args.log_index is not None:
        if not 1 <= args.log_index <= len(logs):
            raise RigError(f"--log {args.log_index}: {args.file} holds {len(logs)} "
                           f"log{'s' if len(logs) != 1 else ''}")
        picked = [picked[args.log_index - 1]]
    outs = [args.out if k == 0 else args.out.with_name(f"{args.out.name}-{k + 1}")
            for k in range(len(picked))]
    for out in outs:
        if out.exists():
            raise RigError(f"--out {out}: already exists (choose a new run folder)")
        check_run_id(out.name, f"--out {out}: the folder's name (the run's id)")
    for out, (number, log) in zip(outs, picked, strict=True):
        source = {"source_file": str(args.file), "format": fmt, "format_taken": how,
                  "log_in_file": number, "logs_in_file": len(logs)}
        meta = {"kind": "flight", "components": {}, "import": source,
                "flight": log.run_meta()}
        write_run(out, pd.DataFrame(log.columns, copy=False), meta)
        cols = ", ".join(log.columns)
        print(f"{out}: imported {log.rows} rows from {args.file} (log {number} of "
              f"{len(logs)}; {fmt}, {how}); columns {cols}")
        for note in log.meta.get("notes", []):
            print(f"{out}: {note}")
    return 0
