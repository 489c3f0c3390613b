"""Speed of the flight model (optimizer.flight): against its speed targets.

1. 10 s of flight at the 1 kHz control rate (a 10 s roll step, all rotors recorded) on
   thesis-e's Case I design, N = 4 (target: < 0.5 s);
2. every feasible N = 4 design of thesis-e flown through ``roll_step`` (target: < 30 s);
3. the same 10 s for N = 8.
Prints wall and CPU time (the CPU time is what this process used: on a shared machine
the wall time also counts other processes), microseconds per tick and, to judge the
machine, the time of one million ``a * b + c`` float operations in Python.

    .venv/bin/python benchmarks/flight_bench.py [--repeats 3]
"""

from __future__ import annotations

import argparse
import dataclasses
import time
import timeit

from optimizer.catalogs.catalog import load_catalog
from optimizer.flight.design import gains_for, setup
from optimizer.flight.maneuvers import MANEUVERS, fly
from optimizer.model.design_model import evaluate_grid
from optimizer.solve.objectives import single
from optimizer.solve.selection import optimize
from optimizer.sweep.ranking import rank

CATALOG = "optimizer/data/catalogs/thesis-e"


def timed(fn) -> tuple[float, float]:
    wall, cpu = time.perf_counter(), time.process_time()
    fn()
    return time.perf_counter() - wall, time.process_time() - cpu


def ten_seconds(catalog, n: int, repeats: int) -> None:
    best = optimize(catalog, single("flight-time"), (n,)).best
    grid = evaluate_grid(catalog, n)
    index = (grid.propeller_ids.index(best.propeller), grid.motor_ids.index(best.motor),
             grid.battery_ids.index(best.battery))
    vehicle, actuator = setup(catalog, grid, index)
    gains = gains_for(actuator)
    man = dataclasses.replace(MANEUVERS["roll_step"], duration_s=10.0)
    runs = [timed(lambda: fly(vehicle, actuator, man, gains=gains)) for _ in range(repeats)]
    wall = min(r[0] for r in runs)
    cpu = min(r[1] for r in runs)
    print(f"10 s at 1 kHz, N = {n} ({vehicle.label}): best of {repeats}: wall {wall:.3f} s, "
          f"CPU {cpu:.3f} s, {cpu / 10_000 * 1e6:.1f} us CPU per tick (target < 0.5 s)")


def sweep(catalog) -> None:
    grid = evaluate_grid(catalog, 4)
    holder = {}
    wall, cpu = timed(lambda: holder.setdefault("r", rank(catalog, grid)))
    r = holder["r"]
    flown = len(r.rows) * MANEUVERS["roll_step"].duration_s
    print(f"thesis-e N = 4 sweep: {len(r.rows)} designs ({flown:.0f} s of flight), wall "
          f"{wall:.2f} s, CPU {cpu:.2f} s (target < 30 s); Spearman rho {r.rho:.3f} over "
          f"{r.n_ranked} designs that hover")


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--repeats", type=int, default=3)
    args = p.parse_args()
    ops = timeit.timeit("a * b + c", "a, b, c = 1.1, 2.2, 3.3", number=1_000_000)
    print(f"machine: 1e6 Python 'a * b + c' in {ops * 1e3:.0f} ms (about 25-40 ms on an "
          "idle modern core)")
    catalog = load_catalog(CATALOG)
    ten_seconds(catalog, 4, args.repeats)
    ten_seconds(catalog, 8, args.repeats)
    sweep(catalog)


if __name__ == "__main__":
    main()
