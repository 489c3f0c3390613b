"""The lab catalog's speed against the folder store, as whole commands.

* A 200-repeat Paper C Step 1 (`rotorbench step --repeats 200`, 204.5 s of rig time) into
  the folder store and into PostgreSQL + S3 (moto's S3 server): recorded into the spool,
  its parts going up to S3 while it records, the rest and its catalog row written before
  the command returns, so when it returns the run is whole in the lab. Each `--times`
  times, interleaved, into one folder store and one spool that keep the runs, as a
  bench's do; printed: the median wall time and its ratio to rig time (target
  >= 100x real time for the lab store), the CPU seconds of the command and of the S3
  server, and what the run is (parts, MB). `--baseline DIR` (another checkout, e.g.
  `git worktree add /tmp/main main`) runs the same commands from there too, interleaved
  with these, so before and after share the machine's load.
* Where the lab store's time goes, for the last run recorded: its upload alone (to a
  fresh key, one PUT per file, and again as pyarrow's default three-request multipart
  uploads), its catalog row, and the Parquet encoding of its parts (as written, and
  plain float64 as before).
* `rotorbench runs --store URL --json` over a catalog of 10,000 runs (made by a
  generator here), wall time of the whole command (target < 1 s).
Starts a throwaway PostgreSQL cluster and moto_server on loopback (tests/services.py).
Usage: python benchmarks/lab_store_bench.py [--repeats 200] [--times 3] [--runs 10000]
       [--baseline DIR]
"""

from __future__ import annotations

import argparse
import importlib.util
import io
import json
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))


def _services() -> object:
    spec = importlib.util.spec_from_file_location("rotorbench_tests_services",
                                                  REPO / "tests" / "services.py")
    assert spec and spec.loader
    mod = importlib.util.module_from_spec(spec)
    sys.modules["rotorbench_tests_services"] = mod
    spec.loader.exec_module(mod)
    return mod


def _children_cpu() -> float:
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def _own_cpu() -> float:
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def _process_cpu(pid: int) -> float:
    """CPU seconds (user + system) of another process so far (the S3 server)."""
    with open(f"/proc/{pid}/stat", encoding="ascii") as fh:
        fields = fh.read().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


@dataclass
class Timed:
    wall_s: float
    cpu_s: float  # the command's own (its process and threads)
    server_cpu_s: float  # the S3 server's meanwhile
    out: str


def _timed(cmd: list[str], env: dict[str, str], cwd: Path, server_pid: int) -> Timed:
    c0, s0, t0 = _children_cpu(), _process_cpu(server_pid), time.perf_counter()
    proc = subprocess.run(cmd, env=env, cwd=cwd, capture_output=True, text=True, timeout=3600)
    wall = time.perf_counter() - t0
    if proc.returncode != 0:
        raise SystemExit(f"{' '.join(cmd[3:])}: exit {proc.returncode}: {proc.stderr[-500:]}")
    return Timed(wall, _children_cpu() - c0, _process_cpu(server_pid) - s0, proc.stdout)


def _run_size(run: Path) -> tuple[int, float]:
    """The number of parts of a run folder and their MB."""
    parts = list((run / "samples.parquet").glob("part-*.parquet"))
    return len(parts), sum(p.stat().st_size for p in parts) / 1e6


def step_runs(args: argparse.Namespace, url: str, env: dict[str, str], tmp: Path,
              server_pid: int) -> Path:
    """The interleaved Step 1 runs; returns the last lab run's spool folder."""
    trees = {"this tree": REPO}
    if args.baseline:
        trees = {"baseline": Path(args.baseline).resolve(), **trees}
    stores = ("folder store", "PostgreSQL + S3")
    got: dict[tuple[str, str], list[Timed]] = {(t, s): [] for t in trees for s in stores}
    sizes: dict[tuple[str, str], tuple[int, float]] = {}
    rig_s = 0.0
    last_lab = tmp
    for _ in range(args.times):
        for tree, where in trees.items():
            for store in stores:
                # one folder store and one spool per tree, kept, as on a bench
                root = tmp / f"{tree.replace(' ', '-')}-{store[:6].strip()}"
                extra = ["--out", str(root)] if store == "folder store" else \
                    ["--store", url, "--spool", str(root)]
                cmd = [sys.executable, "-m", "bench.cli", "step", "--repeats",
                       str(args.repeats), *extra]
                timed = _timed(cmd, {**env, "PYTHONPATH": str(where)}, where, server_pid)
                line = next(ln for ln in timed.out.splitlines() if "samples," in ln)
                rig_s = float(line.rsplit(", ", 1)[1].split(" s)")[0])
                got[tree, store].append(timed)
                run = Path(line.split(": ", 1)[0])
                sizes[tree, store] = _run_size(run)
                if store != "folder store":
                    last_lab = run
    print(f"step --repeats {args.repeats} ({rig_s:.1f} s of rig time), each command "
          f"{args.times} times interleaved; medians:")
    for (tree, store), runs in got.items():
        wall = statistics.median(r.wall_s for r in runs)
        cpu = statistics.median(r.cpu_s for r in runs)
        server = statistics.median(r.server_cpu_s for r in runs)
        parts, mb = sizes[tree, store]
        walls = ", ".join(f"{r.wall_s:.2f}" for r in runs)
        print(f"  {tree:9s} into the {store:15s}: {wall:5.2f} s wall = {rig_s / wall:4.0f}x "
              f"real time (each: {walls}); CPU {cpu:.2f} s command + {server:.2f} s S3 "
              f"server; {parts} parts, {mb:.0f} MB")
    for tree in trees:
        ratio = (statistics.median(r.wall_s for r in got[tree, stores[1]])
                 / statistics.median(r.wall_s for r in got[tree, stores[0]]))
        print(f"  {tree}: lab store / folder store wall time {ratio:.2f}")
    return last_lab


def breakdown(run: Path, url: str, server_pid: int) -> None:
    """Where the lab store's time goes, piece by piece, for one recorded run."""
    import pyarrow.parquet as pq

    from bench.engine.recorder import part_encoding
    from bench.store.lab_catalog import LabCatalog, run_from_meta
    from bench.store.run_data import DataLocation

    files = [p for p in run.rglob("*") if p.is_file() and not p.name.startswith(".")]
    mb = sum(p.stat().st_size for p in files) / 1e6
    print(f"where the lab store's time goes, for the last run ({len(files)} files, "
          f"{mb:.1f} MB):")
    for label, where in (("one PUT per file", "s3://lab/alone"),
                         ("multipart, 3 requests per file",
                          "s3://lab/multipart?allow_delayed_open=false")):
        c0, s0, t0 = _own_cpu(), _process_cpu(server_pid), time.perf_counter()
        DataLocation(where).upload(run, run.name)
        wall = time.perf_counter() - t0
        print(f"  upload alone, {label}: {wall:.2f} s wall ({mb / wall:.0f} MB/s), CPU "
              f"{_own_cpu() - c0:.2f} s client + {_process_cpu(server_pid) - s0:.2f} s "
              "S3 server")
    meta = json.loads((run / "run.json").read_text(encoding="utf-8"))
    catalog = LabCatalog(url)
    row = run_from_meta(meta, data=f"s3://lab/runs/{run.name}", samples=int(meta["rows"]),
                        bench="sim", operator="bench")
    times = []
    for _ in range(5):
        t0 = time.perf_counter()
        catalog.upsert_run(row)
        times.append(time.perf_counter() - t0)
    print(f"  catalog row (connect + upsert): {statistics.median(times) * 1e3:.0f} ms "
          "(median of 5)")
    tables = [pq.read_table(p).combine_chunks()
              for p in sorted((run / "samples.parquet").glob("part-*"))]
    columns = [{c: t.column(c).chunk(0).to_numpy() for c in t.column_names} for t in tables]
    for label, as_written in (("as written", True), ("plain float64, as before", False)):
        c0, size = _own_cpu(), 0
        for table, cols in zip(tables, columns, strict=True):
            buf = io.BytesIO()
            enc = part_encoding(cols) if as_written else {"use_dictionary": False}
            pq.write_table(table, buf, compression="lz4", write_statistics=["t_s"], **enc)
            size += buf.tell()
        print(f"  Parquet encoding {label}: {size / 1e6:.1f} MB, {_own_cpu() - c0:.2f} s CPU")


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


def list_runs(url: str, n: int, env: dict[str, str], server_pid: int) -> None:
    fill(url, n)
    cmd = [sys.executable, "-m", "bench.cli", "runs", "--store", url, "--json"]
    times = []
    for _ in range(5):
        timed = _timed(cmd, env, REPO, server_pid)
        times.append(timed.wall_s)
    count = len(json.loads(timed.out))
    times.sort()
    print(f"runs --store URL --json over {count} catalogued runs: {times[2]:.2f} s "
          f"(median of 5 whole commands; fastest {times[0]:.2f} s)")
    timed = _timed([*cmd, "--bench", "stand-2", "--status", "trip"], env, REPO, server_pid)
    print(f"runs --store URL --json --bench stand-2 --status trip: {timed.wall_s:.2f} s")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--repeats", type=int, default=200)
    ap.add_argument("--times", type=int, default=3, help="runs of each command (3)")
    ap.add_argument("--runs", type=int, default=10_000)
    ap.add_argument("--baseline", help="another checkout to time the same commands from")
    args = ap.parse_args()
    services = _services()
    cores, load = os.cpu_count(), os.getloadavg()[0]
    with tempfile.TemporaryDirectory(prefix="rotorbench-lab-bench-") as tmp, \
            services.postgres_cluster() as pg, services.s3_server() as s3:
        env = {**os.environ, **s3.env, "XDG_CACHE_HOME": f"{tmp}/cache"}
        env.pop("ROTORBENCH_STORE", None)
        os.environ.update(s3.env)  # the breakdown's uploads, in this process
        s3.create_bucket("lab")
        url = pg.url()
        _timed([sys.executable, "-m", "bench.cli", "store", "init", url, "--data",
                "s3://lab/runs"], env, REPO, s3.proc.pid)
        last = step_runs(args, url, env, Path(tmp), s3.proc.pid)
        breakdown(last, url, s3.proc.pid)
        list_runs(url, args.runs, env, s3.proc.pid)
    print(f"machine: {cores} cores; load average {load:.1f} at the start, "
          f"{os.getloadavg()[0]:.1f} at the end")
    return 0


if __name__ == "__main__":
    sys.exit(main())
