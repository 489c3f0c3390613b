"""Time of each of the project's attitude filters on a 4-minute recording at 286 Hz.

The issue's speed target: a 4-minute BROAD-like trial (286 Hz, 68,640 samples) in under
2 s per filter. The recording is synthetic (a tumbling sensor from
``drivers.sim.imu_tumble``, every orientation) so that the timing needs no shared data;
the filters do the same work on any data. Prints CPU time of this process (the filter's
own cost; on a shared, loaded machine the wall time adds the wait for a core) and the
wall time of ``--repeat`` runs.
"""

from __future__ import annotations

import argparse
import sys

from rich.console import Console
from rich.table import Table

from analysis.attitude_filters import PROJECT_FILTERS, run_filter
from analysis.imu_recording import ImuRecording
from drivers.sim.imu_tumble import simulate_tumble


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=240.0)
    ap.add_argument("--rate", type=float, default=285.714)
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args(argv)
    c = simulate_tumble(duration_s=args.seconds, rate_hz=args.rate, seed=0)
    rec = ImuRecording("tumble", c["t_s"], c["gyro"], c["acc"], c["mag"], c["quat"])
    table = Table(title=f"{len(rec.t_s)} samples ({args.seconds:g} s at {args.rate:g} Hz)")
    for col in ("filter", "CPU best (s)", "CPU runs (s)", "wall runs (s)", "target"):
        table.add_column(col)
    for name in PROJECT_FILTERS:
        runs = [run_filter(name, rec) for _ in range(args.repeat)]
        cpu = [r.cpu_seconds for r in runs]
        table.add_row(name, f"{min(cpu):.2f}", " ".join(f"{t:.2f}" for t in cpu),
                      " ".join(f"{r.seconds:.2f}" for r in runs), "< 2 s")
    Console(width=100).print(table)
    return 0


if __name__ == "__main__":
    sys.exit(main())
