"""Speed of ``pareto --from SWEEP.parquet`` (``optimizer.sweep.sweep_file.front``).

Writes a seeded synthetic sweep file (the columns of ``fly --sweep --out``: design keys,
the static model numbers, four figures of five maneuvers, ``can_hover``, ``error``; 8 % of
the rows never rose, 3 % errors, 10 % cannot hover) of each size, then measures:

1. the front of flight time vs roll rise time read from the file (two columns and the
   filters read, the front's rows taken from their row groups);
2. the same file read whole by pandas, for scale (what a naive reader pays first);
3. ``optimizer.solve.pareto.enumerate_front`` on its worst case (every point on the front, so
   the tolerance walk sees every one) against its sort alone (``np.lexsort``).

Prints wall and CPU seconds and ratios (the CPU time is this process's: on a shared
machine the wall time also counts other processes).

    .venv/bin/python benchmarks/sweep_front_bench.py [--rows 100000 1000000]
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq

from optimizer.flight.maneuvers import MANEUVERS
from optimizer.solve.pareto import enumerate_front
from optimizer.sweep.sweep_file import SPEC_KEY, STATIC_KEYS, front, open_sweep


def timed(fn):
    wall, cpu = time.perf_counter(), time.process_time()
    out = fn()
    return out, time.perf_counter() - wall, time.process_time() - cpu


def synthetic(n: int, path: Path, seed: int = 0) -> None:
    rng = np.random.default_rng(seed)
    ids = rng.integers(0, 1000, (n, 3))
    cols: dict[str, object] = {
        "actuators": rng.choice(np.array([4, 6, 8], np.int64), n),
        "propeller": pd.Series(ids[:, 0]).map("P{}".format),
        "motor": pd.Series(ids[:, 1]).map("M{}".format),
        "battery": pd.Series(ids[:, 2]).map("B{}".format),
        "series": np.ones(n, np.int64), "parallel": np.ones(n, np.int64),
        "design_id": pd.Series(np.arange(n)).map("d{}".format),
    }
    tau = rng.uniform(20, 150, n)
    for key in STATIC_KEYS:
        cols[key] = rng.uniform(1, 100, n)
    cols["time_constant_ms"] = tau
    cols["flight_time_min"] = 20 + 0.3 * tau + rng.normal(0, 5, n)
    cols["can_hover"] = rng.random(n) > 0.10
    for m in MANEUVERS:
        rise = 3 * tau + rng.normal(0, 10, n)
        rise[rng.random(n) < 0.08] = np.nan
        cols[f"{m}_rise_time_ms"] = pd.array(np.where(np.isnan(rise), None, rise),
                                             dtype="Float64")
        for fig in ("overshoot_pct", "settling_time_ms", "saturation_pct"):
            cols[f"{m}_{fig}"] = rng.uniform(0, 50, n)
    cols["error"] = np.where(rng.random(n) < 0.03, "diverged", None)
    table = pa.Table.from_pandas(pd.DataFrame(cols), preserve_index=False)
    spec = json.dumps({"catalog": "synthetic", "options": {}, "maneuvers": list(MANEUVERS)})
    pq.write_table(table.replace_schema_metadata({SPEC_KEY: spec.encode()}), path)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rows", type=int, nargs="+", default=[100_000, 1_000_000])
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        for n in args.rows:
            path = Path(tmp) / f"sweep_{n}.parquet"
            synthetic(n, path)
            size_mb = path.stat().st_size / 1e6
            res, wall, cpu = timed(lambda p=path: front(open_sweep(p), "flight-time",
                                                        "roll-rise"))
            _, pwall, pcpu = timed(lambda p=path: pd.read_parquet(p))
            print(f"{n:>10,} rows ({size_mb:.0f} MB, {len(res.front)} front points, "
                  f"{res.considered:,} considered): front {wall:.2f} s wall / {cpu:.2f} s "
                  f"CPU; pandas reads the whole file in {pwall:.2f} s / {pcpu:.2f} s CPU "
                  f"(front / whole read, CPU: {cpu / pcpu:.2f})")
    for n in args.rows:
        x = np.random.default_rng(1).random(n)
        y = 1.0 - x  # every point on the front: the walk's worst case
        res, wall, cpu = timed(lambda x=x, y=y: enumerate_front(x, y, np.ones(x.size, bool)))
        _, swall, scpu = timed(lambda x=x, y=y: np.lexsort((np.arange(x.size), y, x)))
        print(f"{n:>10,} points all on the front ({res.indices.size:,} kept): enumerate_front "
              f"{wall:.2f} s wall / {cpu:.2f} s CPU; its sort alone {swall:.2f} s / "
              f"{scpu:.2f} s CPU (front / sort, CPU: {cpu / max(scpu, 1e-9):.1f})")


if __name__ == "__main__":
    main()
