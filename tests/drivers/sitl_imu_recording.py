"""The firmware-IMU calibration recording of ``test_sitl_imu_rig.py``, run as a user's bench
runs: ``python sitl_imu_recording.py RIG OUT`` in a process and session of its own (the
test starts it with ``rotorbench_tests_sitl.bench_in_namespace``). Inside the suite's
process the bench's FDM feeder (1000 packets a second) and MSP poller shared the suite's
scheduling group with its other workers, and a loaded moment dropped every row for 2 s.

Prints one JSON line: whether every stage completed (with each stage's reason), the
stages' run folders, how many motor updates the firmware sent the feeder, and the errors
closing the rig gave, and the simulated truth the stages recorded.
"""

# Hexapod steps ride in plans.sequences.Sequence, typed as the propulsion bench's (as in
# bench/plans/calibration_sequences.py).
# pyright: reportArgumentType=false

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Any

import numpy as np

from bench.jobs.calibration_stages import run_calibration
from bench.plan_runner.runner import HexapodRunOptions
from bench.plans.calibration_sequences import Move, Rest, SetPivot
from bench.plans.sequences import Sequence
from bench.rig.rig import load_imu_rig
from drivers.factory import open_rig
from drivers.hexapod_motions import Motion, gyro_sines, lever_arm_motion

TILT = np.radians(15.0)
TRANSLATION_M = 0.035  # 0.33 m/s and 3.1 m/s^2 at 1.5 Hz: within 0.6 m/s and 6 m/s^2


def sequences() -> list[Sequence]:
    """Paper A's stages, short enough for the suite (a 47 s recording): sines of 9 degrees
    at 0.4, 0.5, 0.6 Hz (together every 10 s) for the gyro; translations at 1.1, 1.3,
    1.5 Hz under a slow 15 degree conical tilt (0.1 Hz) for the accelerometer, every 10 s;
    10 degrees at 0.6 Hz about each lever axis. Each within the hexapod's limits."""
    trans = [((TRANSLATION_M, f, 0.0),) for f in (1.1, 1.3, 1.5)]
    acc = Motion("acc_translations", 12.0, (*trans, ((TILT, 0.1, 0.0),),
                                            ((TILT, 0.1, np.pi / 2),), ()), 1.0)
    lever: list = [SetPivot()]
    for a in "xyz":
        lever += [Rest(0.5, f"lever_{a}"),
                  Move(lever_arm_motion(a, amplitude_deg=10.0, freq_hz=0.6, duration_s=6.0),
                       f"lever_{a}")]
    return [Sequence("cal_bias", (SetPivot(), Rest(3.0, "bias"))),
            Sequence("cal_gyro", (SetPivot(), Rest(0.5, "gyro"),
                                  Move(gyro_sines(9.0, (0.4, 0.5, 0.6), beats=1), "gyro"),
                                  Rest(0.5, "gyro"))),
            Sequence("cal_acc", (SetPivot(), Rest(0.5, "acc"), Move(acc, "acc"),
                                 Rest(0.5, "acc"))),
            Sequence("cal_lever", (*lever, Rest(0.5, "lever_z")))]


def record(rig: Path, out: Path) -> dict[str, Any]:
    """Record the stages with the settings ``rotorbench calibrate`` uses (the host's 1 s
    watchdog, a device silent for 0.5 s ends the run)."""
    opened: dict[str, Any] = {}

    def opener(rig_view: Any, seed: int | None = None) -> Any:
        opened["bench"] = open_rig(rig_view, seed=seed)
        return opened["bench"]

    run = run_calibration(load_imu_rig(rig), out, sequences=sequences(), open_bench=opener,
                          options=HexapodRunOptions())
    bench = opened["bench"]
    return {"complete": run.complete, "reasons": [s.result.reason for s in run.stages],
            "truth": run.truth,
            "run_dirs": [str(s.run_dir) for s in run.stages],
            "firmware_updates": int(bench.peers["imu"].updates),
            "close_errors": [str(e) for e in bench.close_errors]}


if __name__ == "__main__":
    print(json.dumps(record(Path(sys.argv[1]), Path(sys.argv[2])),
                     default=lambda x: np.asarray(x).tolist()))
