"""Roll/pitch accuracy of Paper B's estimator against established filters, same data.

Data: the BROAD trial 07 (fast rotation, optical reference; CC BY 4.0, Laidig et al.,
Data 6(7), 2021, read from ../shared/data/broad, never copied) over its movement mask, and
a simulated Paper B Stewart-platform test (0.17 rad at 0.2 Hz plus pitch, yaw and
translations; calibrated ADIS16400-class IMU at 400 Hz, 0.4 m lever arm) with the
hexapod's exact attitude as the reference IMU. Every filter gets the same gyro (bias from
the initial rest on BROAD, as Paper B prescribes) and accelerometer; ahrs and VQF run with
their defaults. Prints RMS errors in degrees and run times.
"""

from __future__ import annotations

import math
import os
import sys
import time
import warnings
from collections.abc import Callable
from pathlib import Path

import numpy as np
from rich.console import Console
from rich.table import Table

from analysis.attitude import attitude_errors, estimate_attitude
from drivers.sim.imu_attitude_log import simulate_attitude_log

REPO = Path(__file__).resolve().parents[1]
SHARED = Path(os.environ.get("ROTORBENCH_SHARED_DATA", REPO.parent / "shared" / "data"))
BROAD = SHARED / "broad" / "07_undisturbed_fast_rotation_B.hdf5"

Filter = Callable[[np.ndarray, np.ndarray, np.ndarray, float], np.ndarray]


def _paper_b(gain: float, yaw_aligned: bool = False) -> Filter:
    def run(t: np.ndarray, g: np.ndarray, a: np.ndarray, fs: float) -> np.ndarray:
        return estimate_attitude(t, g, a, gain=gain, yaw_aligned=yaw_aligned)
    return run


def _madgwick(t, g, a, fs):
    from ahrs.filters import Madgwick
    return Madgwick(gyr=g, acc=a, frequency=fs).Q


def _mahony(t, g, a, fs):
    from ahrs.filters import Mahony
    return Mahony(gyr=g, acc=a, frequency=fs).Q


def _vqf(t, g, a, fs):
    from vqf import VQF
    return VQF(1.0 / fs).updateBatch(np.ascontiguousarray(g), np.ascontiguousarray(a))["quat6D"]


def _offline_vqf(t, g, a, fs):
    from vqf import offlineVQF
    return offlineVQF(np.ascontiguousarray(g), np.ascontiguousarray(a), None, 1.0 / fs)["quat6D"]


FILTERS: list[tuple[str, Filter]] = [
    ("Paper B, P_err=0.002", _paper_b(0.002)),
    ("Paper B, P_err=0.001", _paper_b(0.001)),
    ("Paper B, P_err=0.002, yaw-aligned", _paper_b(0.002, True)),
    ("ahrs Madgwick (default)", _madgwick),
    ("ahrs Mahony (default)", _mahony),
    ("VQF (online)", _vqf),
    ("VQF (offline)", _offline_vqf),
]


def _datasets() -> list[tuple[str, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]]:
    out = []
    if BROAD.exists():
        import h5py

        with h5py.File(BROAD, "r") as f:
            g, a = f["imu_gyr"][:], f["imu_acc"][:]
            q, moving = f["opt_quat"][:], f["movement"][:].astype(bool)
            fs = float(f.attrs["sampling_rate"])
        t = np.arange(len(g)) / fs
        g = g - g[: int(np.argmax(moving))].mean(axis=0)
        out.append(("BROAD 07 fast rotation", t, g, a, q, moving))
    else:
        print(f"BROAD trial not found at {BROAD}; simulated data only", file=sys.stderr)
    c = simulate_attitude_log(seed=0)
    g = np.c_[c["gyro_x_rad_s"], c["gyro_y_rad_s"], c["gyro_z_rad_s"]]
    a = np.c_[c["acc_x_m_s2"], c["acc_y_m_s2"], c["acc_z_m_s2"]]
    q = np.c_[c["ref_qw"], c["ref_qx"], c["ref_qy"], c["ref_qz"]]
    out.append(("simulated Paper B hexapod", c["t_s"], g, a, q, np.ones(len(g), bool)))
    return out


def main() -> int:
    table = Table(title="roll / pitch / inclination RMS error (deg), same data for every filter")
    for col in ("data", "filter", "roll", "pitch", "inclination", "run time (s)"):
        table.add_column(col, no_wrap=True)
    for name, t, g, a, q_ref, mask in _datasets():
        fs = (len(t) - 1) / (t[-1] - t[0])
        for label, run in FILTERS:
            start = time.perf_counter()
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                q = run(t, g, a, fs)
            elapsed = time.perf_counter() - start
            e = attitude_errors(q, q_ref, mask)
            table.add_row(name, label, *(f"{math.degrees(v):.2f}" for v in
                                         (e.roll_rms, e.pitch_rms, e.inclination_rms)),
                          f"{elapsed:.2f}")
        table.add_section()
    Console(width=120).print(table)
    return 0


if __name__ == "__main__":
    sys.exit(main())
