"""Run every benchmark script in this folder in turn and show what each prints.

Benchmarks are where speed and accuracy claims come from: each script prints the
numbers it measured on this machine. Usage: ``make bench`` or
``python benchmarks/run_all.py [NAME ...]`` to run only some. ``suite_cpu`` (the test
suite's time, as long as the suite) runs only when named.
"""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
#: run alone, by name: as long as the test suite it measures
ALONE = {"suite_cpu"}


def main(argv: list[str]) -> int:
    wanted = set(argv)
    scripts = sorted(p for p in HERE.glob("*.py") if p.name != Path(__file__).name
                     and (p.stem not in ALONE or p.stem in wanted))
    failures = 0
    for script in scripts:
        if wanted and script.stem not in wanted:
            continue
        print(f"\n=== {script.name}", flush=True)
        start = time.perf_counter()
        proc = subprocess.run([sys.executable, str(script)], check=False)
        print(f"=== {script.name}: exit {proc.returncode}, {time.perf_counter() - start:.1f} s")
        failures += proc.returncode != 0
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
