"""Paper A calibration through the bench (rig path), over several seeds, with timings.

Runs every stage on the simulated IMU bench (``bench/data/rigs/sim-imu.toml``) through the
hexapod runner and recorder, joins the recorded runs into one log, calibrates it and
prints the errors against the simulator's hidden truth: K (relative Frobenius), lever
arm R, gyro-bias z-scores, time offset, and the verification RMS next to Table A.2; plus
the wall time of the runs (the simulated rig runs far faster than real time).
Usage: ``python benchmarks/imu_rig_calibration_bench.py [--seeds N] [--quick-only]``.
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

import numpy as np
from rich.console import Console
from rich.table import Table

from analysis.imu_calibration import TABLE_A2, calibrate
from analysis.imu_log import load_calibration_log
from bench.jobs.calibration_stages import collect_log, run_calibration
from bench.plan_runner.runner import HexapodRunOptions
from bench.rig.rig import default_imu_rig_path, load_imu_rig


def _rel(a, b) -> float:
    a, b = np.asarray(a, float), np.asarray(b, float)
    return float(np.linalg.norm(a - b) / np.linalg.norm(b))


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", type=int, default=4)
    ap.add_argument("--quick-only", action="store_true")
    ap.add_argument("--tick", type=float, default=0.05)
    args = ap.parse_args()
    rig = load_imu_rig(default_imu_rig_path())
    console = Console(width=150)
    print(f"machine load (1, 5, 15 min): {os.getloadavg()}")
    table = Table(title="Paper A calibration through the simulated IMU bench "
                        f"(recorded runs, tick {args.tick:g} s)")
    for col in ("protocol", "seed", "rig s", "wall s", "K_ω err %", "K_a err %", "max|ΔR| mm",
                "bias z", "Δlag ms", "ω RMS max", "a RMS max"):
        table.add_column(col, no_wrap=True)
    modes = (True,) if args.quick_only else (True, False)
    options = HexapodRunOptions(tick_s=args.tick)
    for quick in modes:
        for seed in range(args.seeds):
            with tempfile.TemporaryDirectory() as tmp:
                start = time.perf_counter()
                run = run_calibration(rig, Path(tmp), quick=quick, seed=seed, options=options)
                wall = time.perf_counter() - start
                assert run.complete, [s.result.reason for s in run.stages]
                log = collect_log([s.run_dir for s in run.stages], Path(tmp) / "log.parquet")
                cal = calibrate(load_calibration_log(log), measured_mounting_deg=(0, 0, 17))
            tr = run.truth
            assert tr is not None
            rig_s = sum(s.result.t_end_s for s in run.stages)
            dr = np.abs(np.asarray(cal.lever_arm_m) - tr["lever_arm_from_pivot_m"]).max()
            z = (np.asarray(cal.gyro_bias_rad_s) - tr["gyro_bias_rad_s"]) / \
                np.asarray(cal.gyro_bias_stderr_rad_s)
            v = cal.verification_rms
            table.add_row("quick" if quick else "full", str(seed), f"{rig_s:.0f}",
                          f"{wall:.1f}", f"{100 * _rel(cal.k_gyro, tr['k_gyro']):.3f}",
                          f"{100 * _rel(cal.k_acc, tr['k_acc']):.3f}", f"{dr * 1e3:.2f}",
                          f"{np.abs(z).max():.2f}",
                          f"{(cal.time_offset_s - tr['clock_offset_s']) * 1e3:+.2f}",
                          f"{max(v['gyro_rad_s']['corrected']):.4f}",
                          f"{max(v['acc_m_s2']['corrected']):.4f}")
    console.print(table)
    print(f"targets: K < 0.2 %, |ΔR| < 2 mm, |z| < 3, Table A.2 ω {TABLE_A2['gyro_rad_s']} "
          f"rad/s, a {TABLE_A2['acc_m_s2']} m/s²")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
