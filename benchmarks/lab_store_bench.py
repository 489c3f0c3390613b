"""The lab catalog's speed against the folder store, as whole commands.

* A 200-repeat Paper C Step 1 (`rotorbench step --repeats 200`, 406.5 s of rig time) into
  the folder store and into PostgreSQL + S3 (moto's S3 server; the run recorded into the
  spool and published behind it), side by side: wall time and the ratio of rig time to
  wall time (target >= 100x real time for the lab store).
* `rotorbench runs --store URL --json` over a catalog of 10,000 runs (made by a
  generator here), wall time of the whole command (target < 1 s).
Starts a throwaway PostgreSQL cluster and moto_server on loopback (tests/services.py).
Usage: python benchmarks/lab_store_bench.py [--repeats 200] [--runs 10000]
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
ROTORBENCH = [sys.executable, "-m", "bench.cli"]


def _services() -> object:
    spec = importlib.util.spec_from_file_location("rotorbench_tests_services",
                                                  REPO / "tests" / "services.py")
    assert spec and spec.loader
    mod = importlib.util.module_from_spec(spec)
    sys.modules["rotorbench_tests_services"] = mod
    spec.loader.exec_module(mod)
    return mod


def _timed(cmd: list[str], env: dict[str, str]) -> tuple[float, str]:
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=3600)
    dt = time.perf_counter() - t0
    if proc.returncode != 0:
        raise SystemExit(f"{' '.join(cmd[3:])}: exit {proc.returncode}: {proc.stderr[-500:]}")
    return dt, proc.stdout


def fill(url: str, n: int) -> None:
    import psycopg
    from psycopg.types.json import Jsonb

    with psycopg.connect(url) as con, con.cursor() as cur:
        cur.executemany(
            "INSERT INTO runs (run_id, bench, operator, sequence, components, status, "
            "started_utc, ended_utc, samples, data) VALUES (%s,%s,%s,%s,%s,%s,%s,%s,%s,%s)",
            [(f"gen-{i:06d}", f"stand-{i % 4}", "ana", ("step1", "sweep")[i % 2],
              Jsonb({"motor": f"M{i % 4}", "propeller": f"P{i % 5}", "esc_mode": "diode"}),
              "trip" if i % 97 == 0 else "success", f"2026-01-01T00:00:00.{i:06d}Z",
              "2026-01-01T00:07:00Z", 10_162_500, f"s3://lab/runs/gen-{i:06d}")
             for i in range(n)])


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--repeats", type=int, default=200)
    ap.add_argument("--runs", type=int, default=10_000)
    args = ap.parse_args()
    services = _services()
    with tempfile.TemporaryDirectory(prefix="rotorbench-lab-bench-") as tmp, \
            services.postgres_cluster() as pg, services.s3_server() as s3:
        env = {**os.environ, **s3.env, "XDG_CACHE_HOME": f"{tmp}/cache"}
        env.pop("ROTORBENCH_STORE", None)
        s3.create_bucket("lab")
        url = pg.url()
        _timed([*ROTORBENCH, "store", "init", url, "--data", "s3://lab/runs"], env)
        step = ["step", "--repeats", str(args.repeats)]
        rig_s = None
        rows = {}
        for label, extra in (("folder store", ["--out", f"{tmp}/runs"]),
                             ("PostgreSQL + S3", ["--store", url, "--spool", f"{tmp}/spool"])):
            dt, out = _timed([*ROTORBENCH, *step, *extra], env)
            line = next(ln for ln in out.splitlines() if "samples," in ln)
            rig_s = float(line.rsplit(", ", 1)[1].split(" s)")[0])
            rows[label] = dt
            print(f"step --repeats {args.repeats} into the {label}: {dt:.1f} s wall for "
                  f"{rig_s:.1f} s of rig time = {rig_s / dt:.0f}x real time")
        print(f"lab store / folder store wall time: "
              f"{rows['PostgreSQL + S3'] / rows['folder store']:.2f}")
        fill(url, args.runs)
        times = []
        for _ in range(5):
            dt, out = _timed([*ROTORBENCH, "runs", "--store", url, "--json"], env)
            times.append(dt)
        n = len(json.loads(out))
        times.sort()
        print(f"runs --store URL --json over {n} catalogued runs: {times[2]:.2f} s "
              f"(median of 5 whole commands; fastest {times[0]:.2f} s)")
        dt, _ = _timed([*ROTORBENCH, "runs", "--store", url, "--json", "--bench", "stand-2",
                        "--status", "trip"], env)
        print(f"runs --store URL --json --bench stand-2 --status trip: {dt:.2f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
