"""Speed of the closed-loop design sweep (``rotorbench fly --sweep``, docs/sweeps.md).

Flies one sweep three ways and prints designs per second for each:

1. in this process (``--workers 1``, the default executor);
2. a Dask LocalCluster of 1 worker process (what the cluster path costs over 1);
3. a LocalCluster of 2 worker processes (the 1 -> 2 speed-up).

Cluster start and stop are timed apart from the flying. Then the scheduler's cost per
task: the wall time of N no-op tasks on the 1- and 2-worker clusters, divided by N.
From the measured seconds per design (in this process) and cost per task, it projects
the wall time of the sweep on 64 and 512 worker cores, for one design per task and for
the default chunk of 256: flying (designs x s/design / cores) plus the scheduler
(tasks x s/task, which one scheduler does one after the other).

The sweep: thesis-e, N = 4, the 44 designs that hover with margin (default), or with
``--sizinglab DIR`` the SizingLab flyable set (``rotorbench import-sizinglab --out DIR``
first; ``--flyable --actuators 4 6 8``: long, run it on an idle machine).
``--maneuver`` as the command (default: all five).

    .venv/bin/python benchmarks/sweep_bench.py [--sizinglab DIR] [--maneuver roll_step]
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from bench.jobs.sweep_run import Executor, opened  # noqa: E402
from bench.store.catalogs import with_min_thrust_to_weight  # noqa: E402
from optimizer.catalog import load_catalog  # noqa: E402
from optimizer.flight.maneuvers import MANEUVERS  # noqa: E402
from optimizer.flyable import FlyableBuilder, Rules  # noqa: E402
from optimizer.model_constants import DEFAULT_MIN_THRUST_TO_WEIGHT  # noqa: E402
from optimizer.sweep.chunks import chunk_size, split  # noqa: E402
from optimizer.sweep.designs import plan_designs  # noqa: E402


def noop(i: int) -> int:
    return i


def plan_of(args: argparse.Namespace):
    if args.sizinglab is None:
        catalog = with_min_thrust_to_weight(load_catalog(REPO / "fixtures/catalogs/thesis-e"),
                                            DEFAULT_MIN_THRUST_TO_WEIGHT)
        return "thesis-e N = 4", plan_designs(catalog, [4])
    catalog = with_min_thrust_to_weight(load_catalog(args.sizinglab),
                                        DEFAULT_MIN_THRUST_TO_WEIGHT)
    return (f"SizingLab flyable N = 4, 6, 8 ({args.sizinglab})",
            plan_designs(catalog, [4, 6, 8], build_grid=FlyableBuilder(Rules())))


def fly(plan, maneuvers, executor: Executor) -> dict[str, float]:
    """Seconds to open the executor, to fly every chunk, to close it."""
    t0 = time.perf_counter()
    with opened(executor, lambda _: None) as runner:
        t1 = time.perf_counter()
        chunks = split(plan, maneuvers, chunk_size(len(plan), runner.slots))
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
    p.add_argument("--maneuver", nargs="+", default=list(MANEUVERS), choices=list(MANEUVERS))
    p.add_argument("--noop-tasks", type=int, default=2000)
    args = p.parse_args()
    print(f"machine: {os.cpu_count()} CPUs, load average "
          f"{', '.join(f'{x:.1f}' for x in os.getloadavg())} (other work slows every figure)")
    start = time.perf_counter()
    name, plan = plan_of(args)
    n = len(plan)
    print(f"sweep: {name}: {n} designs x {len(args.maneuver)} maneuvers "
          f"({', '.join(args.maneuver)}); plan built in {time.perf_counter() - start:.2f} s")
    runs = {"in process": Executor(),
            "LocalCluster, 1 worker": Executor(workers=1, local=True),
            "LocalCluster, 2 workers": Executor(workers=2)}
    rates = {}
    for label, executor in runs.items():
        t = fly(plan, args.maneuver, executor)
        rates[label] = n / t["fly"]
        print(f"{label:24s}: {rates[label]:7.2f} designs/s (flying {t['fly']:.2f} s; cluster "
              f"start {t['open']:.2f} s, stop {t['close']:.2f} s)")
    one, two = rates["LocalCluster, 1 worker"], rates["LocalCluster, 2 workers"]
    print(f"speed-up 1 -> 2 workers: {two / one:.2f}x; LocalCluster 1 worker vs in process: "
          f"{one / rates['in process']:.2f}x")
    per_task = {w: overhead(w, args.noop_tasks) for w in (1, 2)}
    for w, s in per_task.items():
        print(f"scheduler overhead, {w} worker(s): {s * 1e3:.2f} ms per task "
              f"({args.noop_tasks} no-op tasks)")
    s_design = 1.0 / rates["in process"]
    o = max(per_task.values())
    print(f"projection from {s_design * 1e3:.1f} ms per design (in process) and {o * 1e3:.2f} "
          "ms per task (the slower cluster), scaling perfect otherwise:")
    for designs in (n, 100_000, 1_000_000):
        for cores in (64, 512):
            for size in dict.fromkeys((1, chunk_size(designs, cores))):
                flying, sched = designs * s_design / cores, -(-designs // size) * o
                wall = max(flying, sched)
                print(f"  {designs:>9} designs, {cores:3d} cores, chunks of {size:3d}: "
                      f"{_duration(wall):>8s} (flying {_duration(flying)}, scheduler "
                      f"{_duration(sched)})")


def _duration(seconds: float) -> str:
    return f"{seconds:.1f} s" if seconds < 120 else f"{seconds / 60:.1f} min"


if __name__ == "__main__":
    main()
