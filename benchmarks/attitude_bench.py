"""Every project filter and peer side by side, scored as BROAD does, on the same samples.

Data: BROAD trial 07 (fast rotation, optical truth; CC BY 4.0, Laidig et al., Data 6(7),
2021, shipped in fixtures/data/broad) over its movement mask; the simulated
Paper B hexapod test (``drivers.sim.imu_attitude_log``: 0.17 rad roll at 0.2 Hz plus
pitch, yaw and translations, calibrated IMU at 400 Hz with 0.4 m lever arm, no
magnetometer); a simulated IMU tumbling through every orientation
(``drivers.sim.imu_tumble``, 60 s at 286 Hz, with magnetometer); and a tour of 26 held
orientations covering the sphere, upside down and pitch ±90° included, joined by turns of
up to 180° (``simulate_orientation_tour``, 81 s at 286 Hz). Peers run with their
packages' defaults. 6D rows: heading scored after removing its constant offset.

Prints a Markdown table (docs/attitude.md holds its output) with inclination, heading and
total RMSE in degrees and the wall and CPU time of each filter.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from analysis.attitude_compare import compare
from analysis.imu_recording import ImuRecording, read_broad
from drivers.sim.imu_attitude_log import simulate_attitude_log
from drivers.sim.imu_tumble import simulate_orientation_tour, simulate_tumble

REPO = Path(__file__).resolve().parents[1]
BROAD = REPO / "fixtures" / "data" / "broad" / "07_undisturbed_fast_rotation_B.hdf5"


def _datasets() -> list[tuple[str, ImuRecording]]:
    out = []
    if BROAD.exists():
        out.append(("BROAD 07 fast rotation", read_broad(BROAD)))
    else:
        print(f"BROAD trial not found at {BROAD}; simulated data only", file=sys.stderr)
    c = simulate_attitude_log(seed=0)
    xyz = "xyz"
    out.append(("simulated Paper B hexapod (6D)", ImuRecording(
        "hexapod", c["t_s"], np.stack([c[f"gyro_{a}_rad_s"] for a in xyz], axis=1),
        np.stack([c[f"acc_{a}_m_s2"] for a in xyz], axis=1), None,
        np.stack([c[k] for k in ("ref_qw", "ref_qx", "ref_qy", "ref_qz")], axis=1))))
    t = simulate_tumble(duration_s=60.0, seed=0)
    out.append(("simulated tumble, every orientation", ImuRecording(
        "tumble", t["t_s"], t["gyro"], t["acc"], t["mag"], t["quat"], t["movement"])))
    t = simulate_orientation_tour(seed=0)
    out.append(("simulated tour of 26 orientations", ImuRecording(
        "tour", t["t_s"], t["gyro"], t["acc"], t["mag"], t["quat"], t["movement"])))
    return out


def main() -> int:
    print("| data | filter | kind | mode | inclination | heading | total | wall (s) | CPU (s) |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    for name, rec in _datasets():
        for i, row in enumerate(compare(rec)):
            d = row.as_dict()
            head = f"{d['heading_rmse_deg']:.2f}" + ("*" if d["mode"] == "6D" else "")
            print(f"| {name if i == 0 else ''} | {d['filter']} | {d['kind']} | {d['mode']} | "
                  f"{d['inclination_rmse_deg']:.2f} | {head} | {d['total_rmse_deg']:.2f} | "
                  f"{d['seconds']:.2f} | {d['cpu_seconds']:.2f} |", flush=True)
    print("\n* 6D: heading relative, scored after removing its constant offset")
    return 0


if __name__ == "__main__":
    sys.exit(main())
