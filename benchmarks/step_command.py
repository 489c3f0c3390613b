"""Benchmark: ``rotorbench step`` as a whole command on the simulated rig.

What a user waits for: a fresh process (Python and imports included), Step 1 of Paper C
at 25 kHz on the default simulated rig, recorded to a run folder. For 20 and 200 repeats
it prints the rig time of the run (from its ``run.json``), the wall time of the command,
their ratio (times faster than real time), the CPU time of the command (less disturbed
by other load on the machine than the wall time) and the dropped samples. The best of a
few runs is shown, with the load average, since a loaded machine only makes it slower.
Prints measured numbers; nothing here is asserted.
"""

from __future__ import annotations

import json
import os
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
ROTORBENCH = Path(sys.executable).with_name("rotorbench")
RUNS = 3


def run_once(repeats: int, out: Path) -> tuple[float, float, float, int]:
    """(rig seconds, wall seconds, CPU seconds, dropped samples) of one command."""
    shutil.rmtree(out, ignore_errors=True)
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    proc = subprocess.run([str(ROTORBENCH), "step", "--repeats", str(repeats), "--out", str(out)],
                          cwd=REPO, capture_output=True, text=True, check=False)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if proc.returncode != 0:
        raise SystemExit(f"rotorbench step failed ({proc.returncode}): {proc.stderr}")
    (meta_path,) = out.glob("*-step1/run.json")
    meta = json.loads(meta_path.read_text(encoding="utf-8"))
    if meta["status"] != "success":
        raise SystemExit(f"{meta_path}: {meta['status']}: {meta['reason']}")
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return float(meta["duration_s"]), wall, cpu, int(meta["dropped_samples"])


def main() -> int:
    if not ROTORBENCH.exists():
        print(f"no {ROTORBENCH}: install the package first (make .venv/.installed)")
        return 1
    print("rotorbench step on the default sim rig (Step 1, 25 kHz), whole command, "
          f"best of {RUNS}")
    print(f"{'repeats':>7} {'rig_s':>7} {'wall_s':>7} {'x realtime':>10} {'cpu_s':>7} "
          f"{'x per cpu':>9} {'dropped':>7}")
    with tempfile.TemporaryDirectory() as d:
        for repeats in (20, 200):
            runs = [run_once(repeats, Path(d) / "runs") for _ in range(RUNS)]
            rig_s = runs[0][0]
            wall = min(r[1] for r in runs)
            cpu = min(r[2] for r in runs)
            drops = max(r[3] for r in runs)
            print(f"{repeats:>7} {rig_s:>7.1f} {wall:>7.2f} {rig_s / wall:>10.1f} {cpu:>7.2f} "
                  f"{rig_s / cpu:>9.1f} {drops:>7}")
    print(f"machine: {os.cpu_count()} cores, load average {os.getloadavg()[0]:.1f} at the end")
    return 0


if __name__ == "__main__":
    sys.exit(main())
