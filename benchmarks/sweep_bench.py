"""Speed of the closed-loop design sweep (``rotorbench fly --sweep``, docs/sweeps.md).

1. The cost of one chunk (a batch flight) against its size, in this process: seconds per
   chunk = a + b x designs (a: numpy's fixed cost per tick, b: per design), fitted over
   chunks of 16 to 1024 designs. Designs per second per core follow for any chunk size.
2. The sweep flown in this process, on a Dask LocalCluster of 1 worker and of 2 worker
   processes, all with the same chunk size: designs per second and the 1 -> 2 speed-up.
   Cluster start and stop are timed apart from the flying.
3. The scheduler's cost per task: the wall time of N no-op tasks, divided by N.
4. A projection to 64 and 512 worker cores for 100,000 and 1,000,000 designs: each core
   flies its share of chunks (cost model of 1.), one scheduler hands out the tasks one
   after the other (3.), and the plan is built before any flying in one process (its
   measured seconds per design): the serial part.

The sweep: thesis-e, N = 4 (44 designs: too few to spread, it shows the fixed costs) or
with ``--sizinglab DIR`` the SizingLab flyable designs of ``--actuators`` (default 4;
``rotorbench import-sizinglab --out DIR`` first). ``--maneuver`` as the command (default
roll_step). Numbers are only as quiet as the machine (the load average is printed).

    .venv/bin/python benchmarks/sweep_bench.py [--sizinglab DIR] [--actuators 4 6 8]
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from bench.jobs.sweep_run import Executor, opened  # noqa: E402
from bench.store.catalogs import with_min_thrust_to_weight  # noqa: E402
from optimizer.catalogs.catalog import load_catalog  # noqa: E402
from optimizer.catalogs.model_constants import DEFAULT_MIN_THRUST_TO_WEIGHT  # noqa: E402
from optimizer.flight.maneuvers import MANEUVERS  # noqa: E402
from optimizer.model.flyable import FlyableBuilder, Rules  # noqa: E402
from optimizer.sweep.chunks import DEFAULT_CHUNK_SIZE, chunk_size, split  # noqa: E402
from optimizer.sweep.designs import plan_designs  # noqa: E402
from optimizer.sweep.fly_rows import fly_chunk  # noqa: E402


def noop(i: int) -> int:
    return i


def plan_of(args: argparse.Namespace):
    if args.sizinglab is None:
        catalog = with_min_thrust_to_weight(load_catalog(REPO / "optimizer/data/catalogs/thesis-e"),
                                            DEFAULT_MIN_THRUST_TO_WEIGHT)
        return "thesis-e N = 4", plan_designs(catalog, [4])
    catalog = with_min_thrust_to_weight(load_catalog(args.sizinglab),
                                        DEFAULT_MIN_THRUST_TO_WEIGHT)
    counts = ", ".join(map(str, args.actuators))
    return (f"SizingLab flyable N = {counts} ({args.sizinglab})",
            plan_designs(catalog, args.actuators, build_grid=FlyableBuilder(Rules())))


def chunk_cost(plan, maneuvers) -> tuple[float, float]:
    """(a, b) of seconds per chunk = a + b x designs, least squares over chunk sizes."""
    sizes, seconds = [], []
    for size in (16, 64, 256, 1024):
        chunk = split(plan.sample(size, replace=len(plan) < size, random_state=size)
                      .reset_index(drop=True), maneuvers, size)[0]
        fly_chunk(chunk)  # warm
        t0 = time.perf_counter()
        fly_chunk(chunk)
        sizes.append(size)
        seconds.append(time.perf_counter() - t0)
        print(f"  chunk of {size:5d}: {seconds[-1]:7.3f} s = {size / seconds[-1]:7.1f} "
              "designs/s")
    b, a = np.polyfit(sizes, seconds, 1)
    return float(a), float(b)


def fly(plan, maneuvers, executor: Executor, size: int) -> dict[str, float]:
    """Seconds to open the executor, to fly every chunk, to close it."""
    t0 = time.perf_counter()
    with opened(executor, lambda _: None) as runner:
        t1 = time.perf_counter()
        chunks = split(plan, maneuvers, size)
        flown = sum(len(rows) for rows in runner.results(chunks))
        t2 = time.perf_counter()
    assert flown == len(plan)
    return {"open": t1 - t0, "fly": t2 - t1, "close": time.perf_counter() - t2}


def overhead(workers: int, tasks: int) -> float:
    """Seconds per no-op task through the scheduler, on a LocalCluster."""
    from distributed import as_completed

    with opened(Executor(workers=workers, local=True), lambda _: None) as runner:
        client = runner.client
        client.gather([client.submit(noop, -1 - i, pure=False) for i in range(workers)])
        start = time.perf_counter()
        futures = [client.submit(noop, i, pure=False) for i in range(tasks)]
        for f in as_completed(futures, loop=client.loop):
            f.result()
        return (time.perf_counter() - start) / tasks


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--sizinglab", type=Path, default=None, metavar="DIR",
                   help="catalog folder of rotorbench import-sizinglab --out DIR")
    p.add_argument("--actuators", type=int, nargs="+", default=[4])
    p.add_argument("--maneuver", nargs="+", default=["roll_step"], choices=list(MANEUVERS))
    p.add_argument("--noop-tasks", type=int, default=2000)
    args = p.parse_args()
    print(f"machine: {os.cpu_count()} CPUs, load average "
          f"{', '.join(f'{x:.1f}' for x in os.getloadavg())} (other work slows every figure)")
    start = time.perf_counter()
    name, plan = plan_of(args)
    plan_s = time.perf_counter() - start
    n = len(plan)
    print(f"sweep: {name}: {n} designs x {len(args.maneuver)} maneuvers "
          f"({', '.join(args.maneuver)}); plan built in {plan_s:.2f} s "
          f"({plan_s / n * 1e3:.2f} ms per design, one process)")
    print("1. one chunk (a batch flight) in this process:")
    a, b = chunk_cost(plan, args.maneuver)
    print(f"  fit: {a:.3f} s + {b * 1e3:.3f} ms x designs per chunk; at the default chunk of "
          f"{DEFAULT_CHUNK_SIZE}: {DEFAULT_CHUNK_SIZE / (a + b * DEFAULT_CHUNK_SIZE):.0f} "
          "designs/s per core")
    size = min(DEFAULT_CHUNK_SIZE, chunk_size(n, 2))
    print(f"2. the whole sweep, chunks of {size}:")
    runs = {"in process": Executor(),
            "LocalCluster, 1 worker": Executor(workers=1, local=True),
            "LocalCluster, 2 workers": Executor(workers=2)}
    rates = {}
    for label, executor in runs.items():
        t = fly(plan, args.maneuver, executor, size)
        rates[label] = n / t["fly"]
        print(f"  {label:24s}: {rates[label]:7.1f} designs/s (flying {t['fly']:.2f} s; "
              f"cluster start {t['open']:.2f} s, stop {t['close']:.2f} s)")
    one, two = rates["LocalCluster, 1 worker"], rates["LocalCluster, 2 workers"]
    print(f"  speed-up 1 -> 2 workers: {two / one:.2f}x; LocalCluster 1 worker vs in "
          f"process: {one / rates['in process']:.2f}x")
    print("3. the scheduler:")
    per_task = {w: overhead(w, args.noop_tasks) for w in (1, 2)}
    for w, s in per_task.items():
        print(f"  {w} worker(s): {s * 1e3:.2f} ms per task ({args.noop_tasks} no-op tasks)")
    o = max(per_task.values())
    print(f"4. projection: chunk cost {a:.3f} s + {b * 1e3:.3f} ms x designs, {o * 1e3:.2f} ms "
          f"per task in one scheduler, plan {plan_s / n * 1e3:.2f} ms per design before the "
          "flying; workers otherwise independent:")
    for designs in (100_000, 1_000_000):
        for cores in (64, 512):
            c = chunk_size(designs, cores)
            tasks = -(-designs // c)
            flying = -(-tasks // cores) * (a + b * c)
            sched = tasks * o
            serial = designs * plan_s / n
            wall = serial + max(flying, sched)
            print(f"  {designs:>9} designs, {cores:3d} cores, chunks of {c:4d}: "
                  f"{_duration(wall):>8s} (plan {_duration(serial)}, flying "
                  f"{_duration(flying)}, scheduler {_duration(sched)})")


def _duration(seconds: float) -> str:
    return f"{seconds:.1f} s" if seconds < 120 else f"{seconds / 60:.1f} min"


if __name__ == "__main__":
    main()
