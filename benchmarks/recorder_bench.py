"""Benchmark: the recorder at ten times the bench's data rate for a long simulated run.

The bench records 25 kHz x 6 channels (throttle, thrust setpoint, thrust, current,
voltage, rpm) plus time. This feeds the recorder 250 kHz x 6 channels (+ t_s) in 10 ms
blocks, like the command loop does, for 10 simulated minutes (``--minutes``), then
checks that every sample is on disk (row counts and time continuity part by part) and
reports throughput, peak memory (tracemalloc for Python/numpy allocations, peak RSS of
the process) and RSS over time, to show that memory stays bounded. Prints measured
numbers only.
"""

from __future__ import annotations

import argparse
import os
import resource
import shutil
import sys
import tempfile
import time
import tracemalloc
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from bench.engine.recorder import BASE_COLUMNS, SAMPLES_DIR, RunRecorder  # noqa: E402

BENCH_RATE_HZ = 25_000.0


def rss_mb() -> float:
    with open("/proc/self/status", encoding="ascii") as fh:
        for line in fh:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024.0
    return float("nan")


def main(argv: list[str]) -> int:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--minutes", type=float, default=10.0)
    ap.add_argument("--factor", type=float, default=10.0, help="times the bench rate (10)")
    ap.add_argument("--block-s", type=float, default=0.01)
    args = ap.parse_args(argv)
    rate = BENCH_RATE_HZ * args.factor
    n_block = round(rate * args.block_s)
    n_blocks = round(args.minutes * 60.0 / args.block_s)
    rng = np.random.default_rng(0)
    # one second of realistic-looking noisy data, reused with fresh timestamps per block
    pool = {c: rng.normal(1.0, 0.05, size=int(rate)) for c in BASE_COLUMNS[1:]}
    pool["throttle_us"] = np.full(int(rate), 1532.5)
    tmp = Path(tempfile.mkdtemp(prefix="recbench-"))
    try:
        tracemalloc.start()
        rec = RunRecorder(tmp / "run", {"benchmark": "recorder"})
        rss = []
        pushed = 0
        in_recorder = 0.0
        t_wall = time.perf_counter()
        for k in range(n_blocks):
            i0 = (k * n_block) % int(rate)
            cols = {"t_s": (k * n_block + np.arange(n_block)) / rate}
            for c, v in pool.items():
                cols[c] = v[i0:i0 + n_block] if i0 + n_block <= v.size else np.resize(v, n_block)
            t0 = time.perf_counter()
            rec.append(cols)
            in_recorder += time.perf_counter() - t0
            pushed += n_block
            if k % round(60.0 / args.block_s) == 0:
                rss.append((k * args.block_s / 60.0, rss_mb()))
        t0 = time.perf_counter()
        meta = rec.finish("success", "benchmark")
        in_recorder += time.perf_counter() - t0
        wall = time.perf_counter() - t_wall
        _, peak_traced = tracemalloc.get_traced_memory()
        tracemalloc.stop()
        rss.append((args.minutes, rss_mb()))
        # verify: every sample on disk, parts contiguous, each part < 1 s of data
        parts = sorted((tmp / "run" / SAMPLES_DIR).glob("part-*.parquet"))
        on_disk = 0
        prev_last = None
        longest = 0.0
        gaps = 0
        for p in parts:
            t = pq.read_table(p, columns=["t_s"])["t_s"].to_numpy()
            on_disk += t.size
            longest = max(longest, t[-1] - t[0])
            if prev_last is not None and not np.isclose(t[0] - prev_last, 1.0 / rate):
                gaps += 1
            prev_last = t[-1]
        size_gb = sum(p.stat().st_size for p in parts) / 1e9
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    sim_s = args.minutes * 60.0
    print(f"recorder: {rate / 1000:.0f} kHz x 6 channels + t_s ({args.factor:g} x the bench's "
          f"25 kHz), {args.block_s * 1000:g} ms blocks, {args.minutes:g} simulated minutes")
    print(f"samples pushed {pushed:,}, on disk {on_disk:,}, dropped {pushed - on_disk:,}, "
          f"rows in run.json {meta['rows']:,}; parts {len(parts)}, longest part "
          f"{longest:.3f} s, gaps between parts {gaps}")
    print(f"time in the recorder {in_recorder:.1f} s for {sim_s:.0f} s of data: "
          f"{sim_s / in_recorder:.1f} x real time at {args.factor:g} x the bench rate "
          f"({pushed / in_recorder / 1e6:.2f} M rows/s, {size_gb / in_recorder * 1000:.0f} MB/s "
          f"to disk; {size_gb:.2f} GB written, lz4); whole loop incl. making data {wall:.1f} s")
    print(f"memory: tracemalloc peak {peak_traced / 1e6:.1f} MB; process peak RSS "
          f"{resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024:.0f} MB; RSS by minute: "
          + ", ".join(f"{m:.0f}:{r:.0f}" for m, r in rss) + " MB")
    print(f"machine: {os.cpu_count()} cores, load average {os.getloadavg()[0]:.1f} at the end")
    return 0 if pushed == on_disk and gaps == 0 else 1


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
