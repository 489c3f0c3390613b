"""Speed of the batch flight (optimizer.flight.batch) against the scalar loop.

Designs per second per core for a 1.5 s roll step at 1 kHz (target: >= 200/s) and the
full 4 s ``roll_step``, for several batch sizes: the feasible N = 4 designs of thesis-e
(48, some cannot hover), tiled to the batch size; the scalar ``fly`` on the same designs
for the ratio. One process, numpy's threads pinned to 1 (per-core numbers; the batch's
arrays are too small for threads to pay anyway). CPU time is this process's own; on a
shared machine the wall time also counts other processes. Also checks that the batch's
figures equal the scalar ones on the designs it timed (it exits 1 if not).

    .venv/bin/python benchmarks/flight_batch_bench.py [--sizes 1 64 256 1024 4096] [--repeats 2]
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"  # before numpy loads

import argparse  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
import timeit  # noqa: E402

from optimizer.catalogs.catalog import load_catalog  # noqa: E402
from optimizer.flight.batch import DesignBatch, fly_batch  # noqa: E402
from optimizer.flight.design import feasible_indices, gains_for, setup  # noqa: E402
from optimizer.flight.maneuvers import MANEUVERS, Maneuver, fly  # noqa: E402
from optimizer.model.design_model import evaluate_grid  # noqa: E402

CATALOG = "optimizer/data/catalogs/thesis-e"
SHORT = Maneuver("roll_step", "roll", MANEUVERS["roll_step"].amplitude, 1.5)


def timed(fn) -> tuple[float, float, object]:
    wall, cpu = time.perf_counter(), time.process_time()
    out = fn()
    return time.perf_counter() - wall, time.process_time() - cpu, out


def scalar_rate(models, man: Maneuver) -> tuple[float, list[dict]]:
    """Designs per CPU second of the scalar loop over every design once."""
    def run():
        return [fly(v, a, man, gains=gains_for(a), record=False).figures for v, a in models]
    _, cpu, figures = timed(run)
    return len(models) / cpu, figures


def batch_rate(models, man: Maneuver, size: int, repeats: int) -> tuple[float, float, list]:
    """Designs per CPU second (best of ``repeats``; building the batch included) of one
    batch of ``size`` designs tiled from ``models``; and the wall time."""
    tiled = [models[i % len(models)] for i in range(size)]
    vehicles, actuators = [m[0] for m in tiled], [m[1] for m in tiled]
    best_cpu, best_wall, figures = float("inf"), float("inf"), []
    for _ in range(repeats):
        wall, cpu, figures = timed(lambda: fly_batch(
            DesignBatch.from_models(vehicles, actuators), man, chunk=size))
        best_cpu, best_wall = min(best_cpu, cpu), min(best_wall, wall)
    return size / best_cpu, size / best_wall, figures


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--sizes", type=int, nargs="+", default=[1, 16, 64, 256, 1024, 4096])
    p.add_argument("--repeats", type=int, default=2)
    args = p.parse_args()
    ops = timeit.timeit("a * b + c", "a, b, c = 1.1, 2.2, 3.3", number=1_000_000)
    print(f"machine: 1e6 Python 'a * b + c' in {ops * 1e3:.0f} ms (about 25-40 ms on an "
          f"idle modern core); load average {os.getloadavg()[0]:.1f}; numpy threads 1")
    catalog = load_catalog(CATALOG)
    grid = evaluate_grid(catalog, 4)
    models = [setup(catalog, grid, idx) for idx in feasible_indices(grid)]
    failures = 0
    for man, label in ((SHORT, "1.5 s roll step"), (MANEUVERS["roll_step"], "4 s roll_step")):
        scalar, reference = scalar_rate(models, man)
        print(f"\n{label} at 1 kHz, thesis-e N = 4 ({len(models)} feasible designs, tiled)")
        print(f"  scalar fly: {scalar:7.1f} designs/s (CPU)")
        sizes = args.sizes if man is SHORT else [s for s in args.sizes if s >= 64]
        for size in sizes:
            cpu_rate, wall_rate, figures = batch_rate(models, man, size, args.repeats)
            same = all(f == reference[i % len(models)] for i, f in enumerate(figures))
            failures += not same
            print(f"  batch {size:5d}: {cpu_rate:7.1f} designs/s (CPU; wall {wall_rate:7.1f}),"
                  f" {cpu_rate / scalar:5.1f}x scalar; figures equal: {same}")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
