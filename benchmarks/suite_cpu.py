"""Where the test suite's time goes: CPU per test file and per kind of child process.

The suite's wall time on a small machine is bounded below twice: by its CPU over the
cores, and by the files that run device stand-ins on the wall clock, which one test
process runs one after another (tests/conftest.py, the device lane). This runs the
suite as ``make test`` does (same test processes, same scheduling) and prints both:

- the machine's busy CPU over the run (``/proc/stat``) and the wall time;
- per test file: the test process's own CPU, its reaped children's, and wall time;
- the device lane's summed wall time (the one unit of work that cannot be split);
- per kind of child Python process (``rotorbench`` command, simulated-device world,
  Dask, other): how many ran and their CPU. Each Python process the suite starts writes
  its own CPU at exit through a ``sitecustomize`` on ``PYTHONPATH`` (one killed by a
  signal writes nothing: Dask workers and killed benches are undercounted). The world
  processes, forked by a zygote, are counted in their zygote's line (it reaps them).

Usage: ``python benchmarks/suite_cpu.py [--workers N] [--top K] [pytest args ...]``
from the repository root with the venv's python (``make`` sets it up); about as long
as ``make test``. Extra arguments go to pytest (a folder, ``-k``, ``-x``).
"""

from __future__ import annotations

import argparse
import collections
import json
import math
import os
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

#: written into the temporary folder put first on every child's PYTHONPATH
SITECUSTOMIZE = '''
import atexit, json, os, sys, time
_out = os.environ.get("SUITE_CPU_DIR")
if _out:
    _t0 = time.monotonic()
    def _write():
        t = os.times()
        try:
            with open(os.path.join(_out, f"proc-{os.getpid()}.json"), "w") as fh:
                json.dump({"argv": list(getattr(sys, "orig_argv", sys.argv)),
                           "cpu_s": t.user + t.system, "wall_s": time.monotonic() - _t0,
                           "children_cpu_s": t.children_user + t.children_system,
                           "test": os.environ.get("PYTEST_CURRENT_TEST")}, fh)
        except OSError:
            pass
    atexit.register(_write)
'''

#: a pytest plugin: per test file, this process's CPU, its reaped children's, wall
PLUGIN = '''
import json, os, time
import pytest
_files = {}
@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_protocol(item, nextitem):
    t0, w0 = os.times(), time.monotonic()
    yield
    t1, w1 = os.times(), time.monotonic()
    row = _files.setdefault(str(item.path), [0.0, 0.0, 0.0])
    row[0] += (t1.user - t0.user) + (t1.system - t0.system)
    row[1] += (t1.children_user - t0.children_user) + (t1.children_system - t0.children_system)
    row[2] += w1 - w0
def pytest_sessionfinish(session):
    out = os.environ.get("SUITE_CPU_DIR")
    if out:
        with open(os.path.join(out, f"files-{os.getpid()}.json"), "w") as fh:
            json.dump(_files, fh)
'''


def machine_speed_s() -> float:
    """CPU seconds of a fixed pure-Python loop (10 million additions), best of three: the
    machine's speed at the time, so that runs hours apart can be compared (this machine's
    varied by half through one day for the same suite)."""
    best = math.inf
    for _ in range(3):
        t0, total = time.process_time(), 0
        for i in range(10_000_000):
            total += i
        best = min(best, time.process_time() - t0)
    return best


def busy_cpu_s() -> float:
    """The machine's busy CPU seconds since boot (all but idle and iowait)."""
    fields = [int(x) for x in Path("/proc/stat").read_text().split("\n", 1)[0].split()[1:]]
    return (sum(fields) - fields[3] - fields[4]) / os.sysconf("SC_CLK_TCK")


def kind_of(argv: list[str]) -> str:
    """What a child Python process was, from its command line."""
    line = " ".join(argv)
    if "world_forks" in line:  # the zygote: its CPU with that of the worlds it forked
        return "simulated-device worlds (drivers.wire_sim.world_forks and its forks)"
    if "exec(eval(sys.stdin" in line or argv[1:3] == ["-m", "pytest"]:  # an xdist worker
        return "pytest"
    called = re.search(r"main\(\[\s*['\"]([\w-]+)", line)  # python -c "...main(['step', ..."
    if called:
        return f"rotorbench {called.group(1)}"
    if "bench.cli" in line or any(a.endswith("/rotorbench") for a in argv[:2]):
        words = [a for a in argv[1:] if not a.startswith("-") and "rotorbench" not in a
                 and a != "bench.cli"]
        return f"rotorbench {words[0] if words else '(no command)'}"
    if "distributed" in line or "dask" in line:
        return "Dask scheduler or worker"
    return f"other: {Path(argv[0]).name} {' '.join(argv[1:3])}"[:80]


def main(argv: list[str]) -> int:
    from tests.conftest import _in_device_lane

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--workers", type=int, default=None,
                    help="test processes (default: the Makefile's, 1.5 per core)")
    ap.add_argument("--top", type=int, default=25, help="rows per table")
    args, pytest_args = ap.parse_known_args(argv)
    cores = os.cpu_count() or 1
    workers = args.workers if args.workers is not None else cores + cores // 2
    with tempfile.TemporaryDirectory(prefix="suite-cpu-") as tmp:
        out = Path(tmp) / "out"
        out.mkdir()
        (Path(tmp) / "sitecustomize.py").write_text(SITECUSTOMIZE)
        (Path(tmp) / "suite_cpu_plugin.py").write_text(PLUGIN)
        env = {**os.environ, "SUITE_CPU_DIR": str(out), "PYTHONDONTWRITEBYTECODE": "",
               "QT_QPA_PLATFORM": "offscreen",
               "PYTHONPATH": os.pathsep.join(filter(None, (tmp, os.environ.get("PYTHONPATH"))))}
        cmd = [sys.executable, "-m", "pytest", "-q", "-p", "suite_cpu_plugin",
               "-n", str(workers), "--dist", "loadfile", "--no-loadscope-reorder",
               *pytest_args]
        speed_before = machine_speed_s()
        busy0, wall0 = busy_cpu_s(), time.monotonic()
        code = subprocess.run(cmd, cwd=REPO, env=env, check=False).returncode
        busy, wall = busy_cpu_s() - busy0, time.monotonic() - wall0
        speed_after = machine_speed_s()
        files: dict[str, list[float]] = collections.defaultdict(lambda: [0.0, 0.0, 0.0])
        workers_wall: list[float] = []
        lane_wall = 0.0
        for path in out.glob("files-*.json"):
            rows = json.loads(path.read_text())
            if rows:  # the controlling process runs no test
                workers_wall.append(sum(r[2] for r in rows.values()))
            for name, row in rows.items():
                files[name] = [a + b for a, b in zip(files[name], row, strict=True)]
                lane_wall += row[2] if _in_device_lane(name) else 0.0
        procs = [json.loads(p.read_text()) for p in out.glob("proc-*.json")]
    print(f"\npytest exit {code}; {workers} test processes on {cores} cores; the machine's "
          f"speed: 10 million Python additions in {speed_before:.2f} s of CPU before the "
          f"suite, {speed_after:.2f} s after")
    print(f"wall {wall:.0f} s, machine busy CPU {busy:.0f} s "
          f"(CPU / cores = {busy / cores:.0f} s: the floor the CPU sets)")
    print(f"device lane: {lane_wall:.0f} s of wall time in one test process (its floor); "
          f"test processes' wall: {', '.join(f'{w:.0f}' for w in sorted(workers_wall))} s")
    own, kids = sum(r[0] for r in files.values()), sum(r[1] for r in files.values())
    print(f"\ntest files: own CPU {own:.0f} s, reaped children {kids:.0f} s")
    print(f"{'CPU s':>7} {'own':>6} {'kids':>6} {'wall':>6}  file")
    for name, (o, k, w) in sorted(files.items(), key=lambda kv: -(kv[1][0] + kv[1][1]))[
            :args.top]:
        lane = "  [lane]" if _in_device_lane(name) else ""
        print(f"{o + k:7.1f} {o:6.1f} {k:6.1f} {w:6.1f}  {Path(name).relative_to(REPO)}{lane}")
    kinds: dict[str, list[float]] = collections.defaultdict(lambda: [0, 0.0])
    for p in procs:
        k = kind_of(p["argv"])
        if k != "pytest":
            kinds[k][0] += 1
            # a zygote's forks end without writing; it reaped them, so its children's
            # CPU is theirs (no other kind adds its children: they write their own)
            kinds[k][1] += p["cpu_s"] + (p.get("children_cpu_s", 0.0)
                                         if "world_forks" in k else 0.0)
    count, cpu = sum(v[0] for v in kinds.values()), sum(v[1] for v in kinds.values())
    print(f"\nchild Python processes that wrote their CPU at exit: {count}, {cpu:.0f} s of CPU")
    print(f"{'CPU s':>7} {'count':>6} {'each':>6}  kind")
    for k, (n, c) in sorted(kinds.items(), key=lambda kv: -kv[1][1])[:args.top]:
        print(f"{c:7.1f} {n:6d} {c / n:6.2f}  {k}")
    return code


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
