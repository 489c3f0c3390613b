"""Real-time factor of the simulated rig at the bench's rates (25 kHz force and current).

Runs Paper C's Step 1 (175 g <-> 325 g, 20 repeats) on the default rig the way the bench
runner does: every tick it sends the command, sleeps on the rig clock and reads every
sensor. Prints simulated time, wall time, CPU time and the real-time factor per tick.

    .venv/bin/python benchmarks/sim_bench.py [--hold 1.5] [--ticks 0.02 0.01 0.0025]
"""

from __future__ import annotations

import argparse
import time

from bench.rig.rig import default_rig_path, load_rig
from drivers.factory import open_rig

G = 9.81


def step1(tick_s: float, hold_s: float, repeats: int, mode: str) -> tuple[float, float, float, int]:
    rig = load_rig(default_rig_path()).with_esc_mode(mode)
    lo = rig.thrust_map.command_for(0.175 * G)
    hi = rig.thrust_map.command_for(0.325 * G)
    n_hold = round(hold_s / tick_s)
    samples = 0
    with open_rig(rig) as r:
        sensors = list(r.sensors.values())
        r.esc.arm()
        wall0, cpu0 = time.perf_counter(), time.process_time()
        for _ in range(repeats):
            for pulse in (lo, hi):
                for _ in range(n_hold):
                    r.esc.set_pulse_us(pulse)
                    r.clock.sleep(tick_s)
                    for s in sensors:
                        samples += len(s.read_block())
        wall, cpu = time.perf_counter() - wall0, time.process_time() - cpu0
        sim = r.clock.now()
    return sim, wall, cpu, samples


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--hold", type=float, default=1.5, help="seconds per level (default 1.5)")
    ap.add_argument("--repeats", type=int, default=20)
    ap.add_argument("--ticks", type=float, nargs="+", default=[0.02, 0.01, 0.0025])
    ap.add_argument("--mode", default="complementary")
    args = ap.parse_args()
    print(f"Paper C Step 1 x {args.repeats}, {args.hold} s per level, 25 kHz load cell + "
          f"current + voltage + rpm, ESC mode {args.mode}")
    print(f"{'tick [ms]':>9} {'sim [s]':>8} {'wall [s]':>9} {'cpu [s]':>8} "
          f"{'x real time':>12} {'(cpu)':>6} {'samples':>10}")
    for tick in args.ticks:
        sim, wall, cpu, n = step1(tick, args.hold, args.repeats, args.mode)
        print(f"{tick * 1e3:9.1f} {sim:8.1f} {wall:9.3f} {cpu:8.3f} {sim / wall:12.0f} "
              f"{sim / cpu:6.0f} {n:10d}")
    print("x real time = simulated / wall seconds; (cpu) = simulated / process CPU seconds, "
          "the figure to read when other jobs share the machine")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
