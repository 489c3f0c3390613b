"""Accuracy of the Paper A calibration on the simulated hexapod, over several seeds.

Simulates the full Paper A protocol (and the shortened test protocol) with the ADIS16400's
noise, calibrates from the log, and prints the errors against the simulated truth: K
(relative Frobenius), lever arm R, gyro-bias z-scores, time offset, and the verification
RMS next to Table A.2. Also shows what ignoring a 20 ms lag costs.
"""

from __future__ import annotations

import sys
import time

import numpy as np
import pandas as pd
from rich.console import Console
from rich.table import Table

from analysis.imu_calibration import TABLE_A2, calibrate
from drivers.sim.hexapod_motions import paper_a_protocol
from drivers.sim.imu import ADIS16400, ImuModel
from drivers.sim.imu_calibration_log import simulate_calibration_log

SEEDS = range(8)


def _rel(k: np.ndarray, k_true: np.ndarray) -> float:
    return float(np.linalg.norm(k - k_true) / np.linalg.norm(k_true))


def main() -> int:
    console = Console(width=140)
    m = ADIS16400
    table = Table(title="Paper A calibration on the simulated rig (ADIS16400 noise, 100 Hz)")
    for col in ("protocol", "seed", "K_ω err %", "K_a err %", "max|ΔR| mm", "max|z| bias",
                "Δlag ms", "ω RMS max rad/s", "a RMS x,y,z m/s²", "s"):
        table.add_column(col, no_wrap=True)
    for short in (False, True):
        for seed in SEEDS:
            start = time.perf_counter()
            df = pd.DataFrame(simulate_calibration_log(
                m, paper_a_protocol(m.rate_hz, short=short), seed=seed))
            cal = calibrate(df)
            elapsed = time.perf_counter() - start
            z = (np.asarray(cal.gyro_bias_rad_s) - m.gyro_bias_rad_s) / \
                np.asarray(cal.gyro_bias_stderr_rad_s)
            v = cal.verification_rms
            table.add_row(
                "short" if short else "full", str(seed),
                f"{100 * _rel(cal.kg, m.k_gyro()):.3f}", f"{100 * _rel(cal.ka, m.k_acc()):.3f}",
                f"{1e3 * np.abs(np.asarray(cal.lever_arm_m) - m.lever_arm_m).max():.2f}",
                f"{np.abs(z).max():.2f}",
                f"{1e3 * (cal.time_offset_s - m.clock_offset_s):+.3f}",
                f"{max(v['gyro_rad_s']['corrected']):.4f}",
                ",".join(f"{x:.3f}" for x in v["acc_m_s2"]["corrected"]),
                f"{elapsed:.2f}")
        table.add_section()
    console.print(table)
    console.print(f"Table A.2 (thesis, corrected): ω {TABLE_A2['gyro_rad_s']} rad/s, "
                  f"a {TABLE_A2['acc_m_s2']} m/s²")

    lag = ImuModel(clock_offset_s=0.020)
    df = pd.DataFrame(simulate_calibration_log(lag, paper_a_protocol(short=True), seed=0))
    ignored, estimated = calibrate(df, time_offset_s=0.0), calibrate(df)
    console.print(
        f"20 ms lag: K_ω error {100 * _rel(ignored.kg, lag.k_gyro()):.3f} % if ignored, "
        f"{100 * _rel(estimated.kg, lag.k_gyro()):.3f} % with the estimated offset "
        f"({1e3 * estimated.time_offset_s:.2f} ms); corrected ω RMS "
        f"{max(ignored.verification_rms['gyro_rad_s']['corrected']):.4f} vs "
        f"{max(estimated.verification_rms['gyro_rad_s']['corrected']):.4f} rad/s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
