"""How the web view reads a 5 M-row run's plots on its first look: ways compared.

A first look runs in a server that has not read the run yet, so each way is timed on its
first call in a fresh process (wall, user and kernel CPU; medians of ``--repeats``):
* ``chunks``: what ``series_of`` does: each part read in turn in the server's thread,
  a batch of 131,072 rows at a time, reduced to min/max bins as it comes;
* ``chunks, dataset scanner``: the same reduction fed by pyarrow's dataset scanner
  (``to_batches``), in this thread or in pyarrow's thread pool;
* ``whole columns``: each plotted column read whole (``pq.read_table``), then decimated
  (the web view until 2026-11).
All give the same points (checked). Usage:
python benchmarks/serve_series_read.py [--rows 5000000] [--repeats 5]
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parents[1]
WAYS = ("chunks", "chunks, dataset scanner", "chunks, dataset scanner, threads",
        "whole columns")


def _scanner(threads: bool) -> None:
    """ColumnChunks fed by pyarrow's dataset scanner instead of one part after another."""
    import numpy as np
    import pyarrow.dataset as ds

    from analysis import run_record

    def read(self: Any, names: list[str], rows: int | None) -> Any:
        data = ds.dataset([str(f) for f in self._files], format="parquet")
        for batch in data.to_batches(columns=names, batch_size=rows or 1 << 30,
                                     use_threads=threads):
            yield {c: np.asarray(batch.column(c).to_numpy(zero_copy_only=False), float)
                   for c in names}

    run_record.ColumnChunks._read = read


def _whole_columns(folder: Path) -> dict[str, Any]:
    """The plots from whole columns, one at a time (the earlier way)."""
    import numpy as np
    import pyarrow.parquet as pq

    from bench.serve.decimate import minmax_decimate
    from bench.serve.run_views import PLOTS, _efficiency_of

    path = folder / "samples.parquet"
    t = pq.read_table(path, columns=["t_s"]).column(0).to_numpy()
    out, kept = {}, {}
    for key in [k for k, _, _ in PLOTS if k != "efficiency_g_w"]:
        try:
            y = pq.read_table(path, columns=[key]).column(0).to_numpy().astype(float)
        except Exception:  # a column the run lacks
            continue
        out[key] = minmax_decimate(t, y, 1500)
        kept[key] = y
    out["efficiency_g_w"] = minmax_decimate(
        t, _efficiency_of(kept["thrust_n"], kept["current_a"], kept["voltage_v"]), 1500)
    return {k: [np.round(a, 6).tolist() for a in v] for k, v in out.items()}


def _child(way: str, folder: Path) -> None:
    """One first call, in this fresh process; prints its times and a digest of the points."""
    import numpy as np

    import bench.serve.run_views  # imports are not the read

    if way.startswith("chunks, dataset scanner"):
        _scanner(threads=way.endswith("threads"))
    before, t0 = resource.getrusage(resource.RUSAGE_SELF), time.perf_counter()
    if way == "whole columns":
        points = _whole_columns(folder)
    else:
        series = bench.serve.run_views.series_of(folder, 1500)
        points = {p["key"]: [p["t"], p["y"]] for p in series["plots"]}
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_SELF)
    digest = float(np.nansum(np.array([v[1] for v in points.values()], dtype=float)))
    print(json.dumps({"wall": wall, "user": after.ru_utime - before.ru_utime,
                      "sys": after.ru_stime - before.ru_stime, "digest": digest,
                      "plots": sorted(points)}))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--rows", type=int, default=5_000_000)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--child", nargs=2, metavar=("WAY", "FOLDER"), help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        _child(args.child[0], Path(args.child[1]))
        return 0
    spec = importlib.util.spec_from_file_location("serve_bench", REPO / "benchmarks" /
                                                  "serve_bench.py")
    assert spec and spec.loader
    serve_bench = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(serve_bench)
    with tempfile.TemporaryDirectory() as tmp:
        rid = serve_bench.make_big_run(Path(tmp), args.rows)
        folder = Path(tmp) / rid
        got: dict[str, list[dict[str, Any]]] = {w: [] for w in WAYS}
        for _ in range(args.repeats):  # the ways take turns: the same load for each
            for way in WAYS:
                out = subprocess.run([sys.executable, __file__, "--child", way, str(folder)],
                                     capture_output=True, text=True, check=True, cwd=REPO)
                got[way].append(json.loads(out.stdout))
        digests = {round(r["digest"], 3) for rows in got.values() for r in rows}
        assert len(digests) == 1, f"the ways disagree: {digests}"
        base = statistics.median(r["wall"] for r in got["chunks"])
        print(f"{args.rows:,}-row run, its plots on a first call (fresh process), medians of "
              f"{args.repeats}:")
        for way, rows in got.items():
            med = {k: statistics.median(r[k] for r in rows) for k in ("wall", "user", "sys")}
            print(f"  {way:34s} wall {med['wall']:.2f} s (max "
                  f"{max(r['wall'] for r in rows):.2f}), user {med['user']:.2f} s, kernel "
                  f"{med['sys']:.2f} s; {med['wall'] / base:.1f}x the chunks' wall")
    return 0


if __name__ == "__main__":
    sys.exit(main())
