"""``bench/data/rigs/betaflight-sitl-imu.toml``: the IMU bench whose IMU under test is the
real firmware (Betaflight 4.6.0 SITL), fed the simulated hexapod's motion through FDM.

One recorded calibration, by a bench in a process, session and network namespace of its
own as a user's (``sitl_imu_recording.py``, which holds the stages), then the commands as
a user types them on the recorded log:
``rotorbench calibrate --from-log`` and ``rotorbench attitude --compare``.

The stages are Paper A's kinds of motion, shortened for the suite (a 47 s recording).
The firmware is set up at launch (rig option ``cli_settings``) with its serial task at
1 kHz and neither accelerometer nor gyro low-pass (they advance once per run of their task,
which a shared host slows, so each lagged the other), and RAW_IMU and ATTITUDE come in one
MSP_MULTIPLE_MSP request with the firmware's clock (MSP_RTC), sent every 5 ms with up to
three in flight; each row is stamped when the firmware served it. Rows that spanned a stall
of the paced clock, or with no FDM packet accepted in the 10 ms before, are dropped
(docs/sim-rig.md, "Real firmware as the IMU"). Measured: idle, K_w 0.065-0.081 %, K_a
0.043-0.069 %, R 0.3-2.5 mm; with four CPU hogs and a fresh-clone suite beside it, K_w
0.167 %, K_a 0.155 %, R 0.3 mm. The bounds stay what loaded runs of the earlier stamping
gave (K_w to 1.3 %, K_a to 3 %, R to 79 mm) until more loaded runs back a tighter one.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from rotorbench_tests_sitl import (
    _preconditions,
    bench_in_namespace,
    no_firmware_left,
    sitl_binary,
)
from scipy.spatial.transform import Rotation

from analysis.imu_calibration import load_calibration
from bench.cli import main
from bench.jobs.calibration_stages import collect_log
from drivers.contracts import IMU_ATTITUDE_CHANNELS, POSE_CHANNELS

pytestmark = pytest.mark.slow(wall_s=75)  # a 47 s recording through the firmware

ROOT = Path(__file__).resolve().parents[2]
RIG = ROOT / "bench" / "data" / "rigs" / "betaflight-sitl-imu.toml"
RECORDING = Path(__file__).with_name("sitl_imu_recording.py")  # the stages and the recording


@pytest.fixture(scope="module")
def recorded(tmp_path_factory: pytest.TempPathFactory):
    """The recording, made by a bench in a process, session and network namespace of its
    own, as a user's (``sitl_imu_recording.py``)."""
    _preconditions()
    sitl_binary()
    root = tmp_path_factory.mktemp("sitl_imu")
    code = (f"import runpy, sys; sys.argv = ['record', {str(RIG)!r}, {str(root / 'runs')!r}]; "
            f"runpy.run_path({str(RECORDING)!r}, run_name='__main__')")
    res = bench_in_namespace(root, code, timeout_s=180.0)
    assert res.returncode == 0, res.stdout[-2000:] + res.stderr[-3000:]
    run = json.loads(res.stdout.strip().splitlines()[-1])
    log = collect_log([Path(d) for d in run["run_dirs"]], root / "cal.parquet")
    return run, log, root


def _rel(a, b) -> float:
    a, b = np.asarray(a, float), np.asarray(b, float)
    return float(np.linalg.norm(a - b) / np.linalg.norm(b))


def test_every_stage_ran_and_the_firmware_stopped(recorded) -> None:
    run, log, root = recorded
    assert run["complete"], run["reasons"]
    assert run["firmware_updates"] > 1000  # the firmware answered the FDM stream throughout
    assert run["close_errors"] == []  # closed cleanly: feeder, connection, firmware
    df = pd.read_parquet(log)
    assert set(IMU_ATTITUDE_CHANNELS) <= set(df.columns)
    no_firmware_left(root)  # the firmware was stopped with the rig, its folder removed


def test_calibrate_on_the_recorded_run_recovers_the_imu_model(recorded, capsys) -> None:
    run, log, root = recorded
    out = root / "cal.json"
    assert main(["calibrate", "--from-log", str(log), "--out", str(out)]) == 0
    capsys.readouterr()
    cal, truth = load_calibration(out), run["truth"]
    k_gyro = _rel(cal.k_gyro, truth["k_gyro"])
    k_acc = _rel(cal.k_acc, truth["k_acc"])
    lever = np.abs(np.asarray(cal.lever_arm_m) - truth["lever_arm_from_pivot_m"]).max()
    z = (np.asarray(cal.gyro_bias_rad_s) - truth["gyro_bias_rad_s"]) / \
        np.asarray(cal.gyro_bias_stderr_rad_s)
    acc_bias = np.abs(np.asarray(cal.acc_bias_m_s2) - truth["acc_bias_m_s2"]).max()
    print(f"K_w {k_gyro:.3%}, K_a {k_acc:.3%}, lever arm {lever * 1e3:.1f} mm, gyro bias "
          f"{np.abs(z).max():.2f} standard errors, acc bias {acc_bias:.3f} m/s^2, time "
          f"offset {cal.time_offset_s * 1e3:.1f} ms")
    # What loaded runs of the earlier stamping resolved (module doc; the firmware's clock
    # now gives about 0.1-0.2 % and a few mm): the firmware's own scales (16.4 counts per
    # deg/s, 1 g = 256) and its frames are right, since a wrong accelerometer unit (2048
    # per g) is 700 % away, a gyro in whole deg/s 1500 %, a flipped axis or mounting sign
    # 60 % or more. 16.4 against 16.384 (0.1 %) the RAW_IMU test of test_msp_tcp_sitl.py
    # tells. The bounds stay 20x under a unit error.
    assert k_gyro < 0.01
    assert k_acc < 0.03
    assert np.all(np.abs(z) < 4.0)
    assert acc_bias < 0.5  # 13 counts of 1/256 g
    assert lever < 0.03  # R is (0.365, -0.235, 0.230) m: a flipped sign is 0.46 m or more
    # the model's sensor latency, give or take the firmware's filters and where in the
    # MSP round trip (stamped at the request) the firmware read its sensors
    assert abs(cal.time_offset_s - truth["clock_offset_s"]) < 0.015


def test_the_firmware_attitude_is_the_echoed_platform_attitude(recorded, capsys) -> None:
    """The SITL computes no attitude (USE_IMU_CALC is off): MSP_ATTITUDE is the FDM
    quaternion back, so it matches the hexapod's pose to MSP's resolution (0.1 deg roll and
    pitch, 1 deg heading) plus the poll's timing; ``rotorbench attitude --compare`` shows
    it as the device row beside the estimators."""
    _, log, _ = recorded
    df = pd.read_parquet(log)
    fc = Rotation.from_quat(df[list(IMU_ATTITUDE_CHANNELS)].to_numpy(), scalar_first=True)
    pose = Rotation.from_euler("xyz", df[list(POSE_CHANNELS[3:])].to_numpy())
    err = np.degrees((pose.inv() * fc).magnitude())
    print(f"MSP_ATTITUDE vs the hexapod pose: median {np.median(err):.2f} deg, "
          f"95th percentile {np.percentile(err, 95):.2f} deg")
    assert np.median(err) < 1.0
    capsys.readouterr()
    assert main(["attitude", str(log), "--compare", "--peers", "vqf-6d", "--json"]) == 0
    scores = {r["filter"]: r for r in json.loads(capsys.readouterr().out)["scores"]}
    device = scores["device (own attitude)"]
    assert device["kind"] == "device"
    print(f"attitude vs the reference IMU: device {device['total_rmse_deg']:.2f} deg, "
          f"vqf-6d {scores['vqf-6d']['total_rmse_deg']:.2f} deg")
    assert device["total_rmse_deg"] < 1.5  # measured 0.58-1.10 deg, loaded runs the most
