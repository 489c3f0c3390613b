"""``rotorbench import FILE [--format F] --out DIR``: another bench's log as a run folder.

The format is read from the header unless ``--format`` forces it (``--map`` implies csv);
the output line says which was taken and how.

Parsing lives in ``analysis.importers``; this is the glue that writes the run folder with
``bench.engine.recorder.RunRecorder`` into a temporary folder beside ``DIR`` and renames it into
place, so an interrupted import leaves nothing half-written under the final name.
"""

from __future__ import annotations

import argparse
import itertools
import shutil
from pathlib import Path

import numpy as np

from bench.errors import RigError

COMMAND = "import"


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        COMMAND, help="import a thrust-stand log (RCbenchmark, ESC32, any CSV) as a run",
        description="Reads another bench's log and writes a run folder with the run's column "
                    "names and SI units (units from the file's column names). A CSV whose "
                    "columns already carry run names (t_s, throttle_us, thrust_n, rpm, ...) "
                    "needs no --map. The format is detected from the header; --format "
                    "forces one, --map implies csv.")
    p.add_argument("file", type=Path, help="log file")
    p.add_argument("--format", dest="fmt", choices=("rcbenchmark", "esc32", "csv"),
                   default=None, help="force the format (default: detected from the header)")
    p.add_argument("--map", dest="mapping", action="append", default=[],
                   metavar="RUNCOL=FILECOL", help="csv only: take a run column from a file "
                                                  "column (repeatable)")
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


def write_run(out: Path, samples, meta: dict) -> Path:
    """Write ``samples`` (a DataFrame with run columns) and ``meta`` as a run folder; the
    run's reason names the log (``meta["import"]["source_file"]``)."""
    from bench.engine.recorder import BASE_COLUMNS, RunRecorder

    out = Path(out)
    if out.exists():
        raise RigError(f"--out {out}: already exists (choose a new run folder)")
    tmp = out.with_name(f".{out.name}.importing")
    if tmp.exists():
        shutil.rmtree(tmp)
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise RigError(f"--out {out}: cannot create its folder {out.parent} "
                       f"({exc.strerror or exc})") from None
    n = len(samples)
    cols = {c: samples[c].to_numpy(dtype=float) for c in samples.columns}
    for c in BASE_COLUMNS:  # the recorder's schema: absent channels are NaN
        cols.setdefault(c, np.full(n, np.nan))
    try:
        rec = RunRecorder(tmp, {"id": out.name, **meta})
        # append in slices so the recorder writes its usual <= 1 s parts
        t = cols["t_s"]
        # a cut where the whole second since the start changes: O(rows), whatever the gaps
        cuts = np.flatnonzero(np.diff(np.floor(t - t[0]))) + 1
        bounds = [0, *cuts.tolist(), n]
        for a, b in itertools.pairwise(bounds):
            if b > a:
                rec.append({c: v[a:b] for c, v in cols.items()})
        rec.finish("success", f"imported from {meta['import']['source_file']}",
                   duration_s=float(t[-1] - t[0]))
        tmp.rename(out)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
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
