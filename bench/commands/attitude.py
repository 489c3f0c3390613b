"""``rotorbench attitude LOG``: orientation of an IMU recording, scored where it has truth.

LOG is a BROAD HDF5 trial or a project IMU log (CSV/Parquet: ``t_s``, gyro and
accelerometer columns, optionally ``mag_*_ut``, ``ref_qw..ref_qz``, ``movement``).
``--cal`` applies a Paper A calibration first; ``--out`` writes one row per sample
(``t_s, qw, qx, qy, qz`` sensor to earth, ENU, and roll/pitch/yaw in degrees); with a
reference the BROAD scores are printed (``--json`` for JSON); ``--compare`` adds the peers
and a PNG of the errors over time.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd
from rich.console import Console
from rich.table import Table

from analysis import quaternion as quat
from analysis.attitude_compare import ComparisonRow, compare, error_figure, score_run
from analysis.attitude_filters import (
    PAPER_B_ACC_TAU_S,
    PAPER_B_EARTH_LP_S,
    PAPER_B_PRINTED_TAU_S,
    PAPER_B_TAU_S,
    PEERS,
    PROJECT_FILTERS,
    FilterRun,
    available,
    paper_b,
    paper_b_printed,
    run_filter,
)
from analysis.calibrated_recording import calibrate_recording
from analysis.errors import LogError
from analysis.imu_calibration import load_calibration
from analysis.imu_log import write_table
from analysis.imu_recording import ImuRecording, load_recording
from bench.paths.outputs import check_writable

_PAPER_B_FILTERS = ("paper-b", "paper-b-printed")
_PAPER_B_OPTIONS = ("gain", "acc_lowpass", "bias_seconds")


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "attitude", help="orientation of an IMU log or BROAD trial; scores, peers side by side",
        description="Estimate the orientation (sensor to earth, ENU) of every sample of an "
                    "IMU log or a BROAD HDF5 trial; score it against a reference as the "
                    "BROAD benchmark does.")
    p.add_argument("log", type=Path, metavar="LOG", help="BROAD trial (.hdf5) or IMU log "
                   "(.csv/.parquet)")
    p.add_argument("--filter", choices=tuple(PROJECT_FILTERS), default="default",
                   help="default: VQF offline (6D/9D); default-causal: VQF sample by sample; "
                        "paper-b: Paper B's filter, accelerometer low-passed in the earth "
                        "frame (6D); paper-b-printed: Paper B's correction as printed (6D)")
    p.add_argument("--6d", dest="six_d", action="store_true",
                   help="ignore the magnetometer (6D estimate, heading not absolute)")
    p.add_argument("--cal", type=Path, metavar="CAL.json",
                   help="apply this Paper A calibration (bias, K, mounting, lever arm) first")
    p.add_argument("--out", type=Path, metavar="FILE",
                   help="write t_s, qw..qz, roll/pitch/yaw_deg (.csv or .parquet)")
    p.add_argument("--json", action="store_true", help="print the scores as JSON only")
    p.add_argument("--compare", action="store_true",
                   help="also run the peers (VQF, Madgwick, Mahony) on the same samples")
    p.add_argument("--peers", metavar="NAMES",
                   help="with --compare: only these peers, comma-separated (default all: "
                        f"{', '.join(PEERS)})")
    p.add_argument("--png", type=Path, metavar="FILE",
                   help="write the error-over-time figure of --compare to this PNG")
    g = p.add_argument_group("paper-b and paper-b-printed options")
    g.add_argument("--gain", type=float, metavar="P",
                   help=f"blend gain P_err per sample, 0..1 (default t_s/{PAPER_B_TAU_S:g} s; "
                        f"printed: t_s/{PAPER_B_PRINTED_TAU_S:g} s)")
    g.add_argument("--acc-lowpass", type=float, metavar="G",
                   help="accelerometer low-pass gain G_a of (B.28), 0..1 (0: off; default "
                        f"paper-b off, printed exp(-t_s/{PAPER_B_ACC_TAU_S * 1000:g} ms))")
    g.add_argument("--bias-seconds", type=float, metavar="S",
                   help="fixed gyro bias: the mean of the first S seconds (instead of the "
                        "bias estimated at every rest)")
    g.add_argument("--earth-lowpass", type=float, metavar="S",
                   help="paper-b: time constant of the earth-frame accelerometer low-pass, "
                        f"seconds (default {PAPER_B_EARTH_LP_S:g}; 0: none)")
    g.add_argument("--yaw-aligned", action="store_true",
                   help="paper-b-printed: Paper B's body-frame accelerometer quaternion given "
                        "the heading (not valid upside down; default: the estimate-frame "
                        "form)")
    p.set_defaults(func=handler)


def _check_args(args: argparse.Namespace) -> None:
    if args.gain is not None and not 0.0 <= args.gain <= 1.0:
        raise LogError(f"--gain: P_err must be in [0, 1], got {args.gain}")
    if args.acc_lowpass is not None and not 0.0 <= args.acc_lowpass < 1.0:
        raise LogError(f"--acc-lowpass: G_a must be in [0, 1), got {args.acc_lowpass}")
    if args.bias_seconds is not None and not (math.isfinite(args.bias_seconds)
                                              and args.bias_seconds >= 0):
        raise LogError(f"--bias-seconds: expected a number of seconds >= 0, "
                       f"got {args.bias_seconds:g}")
    if args.earth_lowpass is not None and not (math.isfinite(args.earth_lowpass)
                                               and args.earth_lowpass >= 0):
        raise LogError(f"--earth-lowpass: expected a number of seconds >= 0, "
                       f"got {args.earth_lowpass:g}")
    used = [o for o in _PAPER_B_OPTIONS if getattr(args, o) is not None]
    if used and args.filter not in _PAPER_B_FILTERS:
        opt = "--" + used[0].replace("_", "-")
        raise LogError(f"{opt}: a paper-b option; add --filter paper-b (or paper-b-printed)")
    if args.earth_lowpass is not None and args.filter != "paper-b":
        raise LogError("--earth-lowpass: a paper-b option; add --filter paper-b")
    if args.yaw_aligned and args.filter != "paper-b-printed":
        raise LogError("--yaw-aligned: an option of Paper B's printed correction; add "
                       "--filter paper-b-printed")
    if args.png is not None and not args.compare:
        raise LogError("--png: the figure belongs to --compare")
    if args.peers is not None:
        if not args.compare:
            raise LogError("--peers: the peers belong to --compare")
        names = [n.strip() for n in args.peers.split(",") if n.strip()]
        unknown = [n for n in names if n not in PEERS]
        if unknown or not names:
            raise LogError(f"--peers: unknown peer {unknown[0] if unknown else '(none)'!r}; "
                           f"known: {', '.join(PEERS)}")
        args.peers = names
    if args.out is not None and args.out.suffix.lower() not in (".csv", ".parquet"):
        raise LogError(f"{args.out}: output must end in .csv or .parquet")
    if args.png is not None and args.png.suffix.lower() != ".png":
        raise LogError(f"{args.png}: the figure is a PNG; name it *.png")
    for path, flag in ((args.out, "--out"), (args.png, "--png")):
        if path is not None:
            check_writable(path, flag, folder=False, inputs=(args.log, args.cal))


def _paper_b_run(rec: ImuRecording, args: argparse.Namespace) -> FilterRun:
    """paper-b or paper-b-printed with the command's options."""
    start, cpu = time.perf_counter(), time.process_time()
    common = {"gain": args.gain, "bias_seconds": args.bias_seconds,
              "acc_lowpass": args.acc_lowpass}
    if args.filter == "paper-b":
        lp = PAPER_B_EARTH_LP_S if args.earth_lowpass is None else args.earth_lowpass
        q = paper_b(rec, earth_lowpass_s=lp, **common)
    else:
        q = paper_b_printed(rec, tilt="yaw-aligned" if args.yaw_aligned else "estimate",
                            **common)
    return FilterRun(args.filter, q, False, time.perf_counter() - start,
                     time.process_time() - cpu)


def _load(args: argparse.Namespace) -> ImuRecording:
    rec = load_recording(args.log)
    norm = np.linalg.norm(rec.acc_m_s2, axis=1)
    if np.any(norm == 0):
        i = int(np.flatnonzero(norm == 0)[0])
        raise LogError(f"{args.log}: row {i + 1}: accelerometer reads exactly zero; "
                       "the estimator needs the gravity direction")
    if args.cal is not None:
        rec = calibrate_recording(rec, load_calibration(args.cal), args.cal)
    return rec


def _table(rows: list[ComparisonRow], title: str) -> Table:
    table = Table(title=title)
    for col in ("filter", "kind", "mode", "inclination", "heading", "total", "samples",
                "wall (s)", "CPU (s)"):
        table.add_column(col, justify="left" if col in ("filter", "kind") else "right",
                         no_wrap=True)
    for r in rows:
        d = r.score.as_deg()
        head = f"{d['heading_rmse_deg']:.3f}" + ("*" if not r.run.nine_d else "")
        table.add_row(r.label, r.kind, "9D" if r.run.nine_d else "6D",
                      f"{d['inclination_rmse_deg']:.3f}", head, f"{d['total_rmse_deg']:.3f}",
                      str(d["samples"]), f"{r.run.seconds:.2f}", f"{r.run.cpu_seconds:.2f}")
    return table


def _write_estimate(rec: ImuRecording, q: np.ndarray, path: Path) -> None:
    rpy = np.degrees(quat.to_euler(q))  # (B.6): Z-Y-X, yaw about up from east
    out = pd.DataFrame({"t_s": rec.t_s, "qw": q[:, 0], "qx": q[:, 1], "qy": q[:, 2],
                        "qz": q[:, 3], "roll_deg": rpy[:, 0], "pitch_deg": rpy[:, 1],
                        "yaw_deg": rpy[:, 2]})
    write_table(out, path)


def handler(args: argparse.Namespace) -> int:
    _check_args(args)
    rec = _load(args)
    if args.compare and rec.ref_quat is None:
        raise LogError(f"{args.log}: --compare needs a reference orientation (BROAD opt_quat "
                       "or ref_qw..ref_qz) to score against")
    if args.compare and isinstance(args.peers, list):
        need_mag = [n for n in args.peers if not available(n, rec)]
        if need_mag:  # named by the user: dropping it from the table would hide it
            raise LogError(f"--peers {need_mag[0]}: a 9D peer needs a magnetometer and "
                           f"{args.log} has none (mag_x_ut..mag_z_ut or imu_mag); use "
                           f"{need_mag[0].replace('9d', '6d')}")
    console = Console(file=sys.stderr if args.json else sys.stdout, width=120)
    if args.filter in _PAPER_B_FILTERS:
        run = _paper_b_run(rec, args)
    else:
        run = run_filter(args.filter, rec, six_d=args.six_d)
    mags = "magnetometer" if rec.mag_ut is not None else "no magnetometer"
    console.print(f"{args.log}: {len(rec.t_s)} samples at {rec.rate_hz:.1f} Hz, {mags}; "
                  f"filter {args.filter} ({'9D' if run.nine_d else '6D'}) in {run.seconds:.2f} s"
                  + (f"; calibration {args.cal}" if args.cal else ""))
    rows: list[ComparisonRow] = []
    if rec.ref_quat is not None:
        label = f"{args.filter} ({'9D' if run.nine_d else '6D'})"
        rows.append(ComparisonRow(label, "project", run, score_run(rec, run)))
        if args.compare:
            rows += [r for r in compare(rec, True if args.peers is None else args.peers)
                     if r.label != label]
    elif args.out is None:
        console.print("no reference attitude in the log (ref_qw..ref_qz or opt_quat) to "
                      "compare with; --out FILE writes the estimate")
    if args.out is not None:
        args.out.parent.mkdir(parents=True, exist_ok=True)  # as the other commands do
        _write_estimate(rec, run.quat, args.out)
        print(f"wrote {args.out}", file=sys.stderr)
    if args.png is not None:  # only when asked: no file in the current folder unasked
        args.png.parent.mkdir(parents=True, exist_ok=True)
        error_figure(rec, rows, args.png, title=f"{args.log.name}: error over time")
        print(f"wrote {args.png}", file=sys.stderr)
    if args.json:
        print(json.dumps({"log": str(args.log), "calibration": str(args.cal or ""),
                          "scores": [r.as_dict() for r in rows]}, indent=2))
    elif rows:
        console.print(_table(rows, "orientation error vs reference, RMSE over movement (deg)"))
        if any(not r.run.nine_d for r in rows):
            console.print("* 6D: heading is relative; scored after removing its constant "
                          "offset")
    return 0
