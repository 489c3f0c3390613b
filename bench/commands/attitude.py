"""``rotorbench attitude LOG``: Paper B's quaternion attitude estimator on an IMU log.

The log has ``t_s, gyro_{x,y,z}_rad_s, acc_{x,y,z}_m_s2`` and optionally a scalar-first
reference quaternion ``ref_qw, ref_qx, ref_qy, ref_qz``; with a reference the roll, pitch
and inclination RMS errors are printed.
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import numpy as np
import pandas as pd
from rich.console import Console
from rich.table import Table

from analysis import quaternion as quat
from analysis.attitude import attitude_errors, estimate_attitude
from analysis.errors import LogError
from analysis.imu_log import (
    ACC_COLUMNS,
    GYRO_COLUMNS,
    REF_QUAT_COLUMNS,
    load_attitude_log,
    write_table,
)
from bench.commands._output import check_writable


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser("attitude", help="quaternion attitude estimate (Paper B) of a log")
    p.add_argument("log", type=Path, metavar="LOG", help="IMU log (.csv/.parquet)")
    p.add_argument("--gain", type=float, default=0.002, metavar="P",
                   help="blend gain P_err per sample, 0..1 (default 0.002, Paper B)")
    p.add_argument("--acc-lowpass", type=float, default=0.0, metavar="G",
                   help="accelerometer low-pass gain G_a of (B.28), 0..1 (default 0: off)")
    p.add_argument("--bias-seconds", type=float, default=0.0, metavar="S",
                   help="average the gyro over the first S seconds (at rest) as its bias")
    p.add_argument("--yaw-aligned", action="store_true",
                   help="give the accelerometer quaternion the current heading (not in Paper B)")
    p.add_argument("--out", type=Path, metavar="FILE",
                   help="write t_s, q_w..q_z, roll/pitch and the (B.26) controller input")
    p.set_defaults(func=handler)


def handler(args: argparse.Namespace) -> int:
    if not 0.0 <= args.gain <= 1.0:
        raise LogError(f"--gain: P_err must be in [0, 1], got {args.gain}")
    if not 0.0 <= args.acc_lowpass < 1.0:
        raise LogError(f"--acc-lowpass: G_a must be in [0, 1), got {args.acc_lowpass}")
    if not (math.isfinite(args.bias_seconds) and args.bias_seconds >= 0):
        raise LogError(f"--bias-seconds: expected a number of seconds >= 0, "
                       f"got {args.bias_seconds:g}")
    if args.out is not None:
        check_writable(args.out, "--out", folder=False, make_parents=False)
    df = load_attitude_log(args.log)
    t = df["t_s"].to_numpy()
    gyro = df[list(GYRO_COLUMNS)].to_numpy()
    acc = df[list(ACC_COLUMNS)].to_numpy()
    if np.any(np.linalg.norm(acc, axis=1) == 0):
        i = int(np.flatnonzero(np.linalg.norm(acc, axis=1) == 0)[0])
        raise LogError(f"{args.log}: row {i + 1}: accelerometer reads exactly zero; "
                       "the estimator needs the gravity direction")
    bias = np.zeros(3)
    if args.bias_seconds > 0:
        rest = t <= t[0] + args.bias_seconds
        bias = gyro[rest].mean(axis=0)
    q = estimate_attitude(t, gyro - bias, acc, gain=args.gain, acc_lowpass=args.acc_lowpass,
                          yaw_aligned=args.yaw_aligned)
    console = Console()
    rate = (len(t) - 1) / (t[-1] - t[0]) if len(t) > 1 else float("nan")
    console.print(f"{args.log}: {len(t)} samples at {rate:.1f} Hz, P_err = {args.gain:g}, "
                  f"G_a = {args.acc_lowpass:g}, gyro bias {np.round(bias, 5).tolist()} rad/s")
    if all(c in df.columns for c in REF_QUAT_COLUMNS):
        e = attitude_errors(q, df[list(REF_QUAT_COLUMNS)].to_numpy())
        table = Table(title="attitude error vs reference (RMS)")
        for col in ("roll", "pitch", "inclination", "samples"):
            table.add_column(col)
        table.add_row(*(f"{math.degrees(v):.3f}°" for v in
                        (e.roll_rms, e.pitch_rms, e.inclination_rms)), str(e.samples))
        console.print(table)
    elif args.out is None:
        console.print("no reference attitude in the log (ref_qw..ref_qz) to compare with; "
                      "--out FILE writes the estimate")
    if args.out is not None:
        rpy = quat.to_euler(q)
        u = quat.controller_input(q)
        out = pd.DataFrame({"t_s": t, "q_w": q[:, 0], "q_x": q[:, 1], "q_y": q[:, 2],
                            "q_z": q[:, 3], "roll_rad": rpy[:, 0], "pitch_rad": rpy[:, 1],
                            "u_x": u[:, 0], "u_y": u[:, 1], "u_z": u[:, 2]})
        write_table(out, args.out)
        print(f"wrote {args.out}", file=sys.stderr)
    return 0
