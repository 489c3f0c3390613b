"""``rotorbench calibrate`` on the rig: every Paper A stage as a recorded run, then the fit.

Loads the IMU-bench rig (default: the simulated one), prints the plans on ``--dry-run``,
otherwise runs the stages with a progress bar on stderr (Ctrl-C or SIGTERM stop the
hexapod, record the run and exit 130), joins the stages into one calibration log next to
the runs, calibrates it and prints the results in the shape of Paper A's tables (and, on a
simulated rig, against the simulator's truth).
"""

from __future__ import annotations

import argparse
import math
import sys
import threading
import tomllib

import numpy as np
from rich.console import Console
from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn
from rich.table import Table

from analysis.imu_calibration import Calibration
from analysis.imu_log import load_calibration_log
from bench.calibration_sequences import HexapodPlan, HexapodSegment, format_plan, paper_a_sequences
from bench.calibration_session import CalibrationRun, collect_log, plans_for, run_calibration
from bench.cli_support import check_writable
from bench.commands._bench_common import (
    _sigterm_as_interrupt,
    erase_on_user_error,
    err_console,
    say_where_an_interrupted_run_went,
)
from bench.commands.calibrate import (
    _check_out,
    calibrate_frame,
    finish,
    print_calibration,
    vec,
)
from bench.errors import RigError
from bench.hexapod_runner import HexapodRunOptions
from bench.imu_rig import default_imu_rig_path, is_imu_rig, load_imu_rig
from bench.recorder import new_run_id

__all__ = ["run_on_rig"]


def _load(args: argparse.Namespace):
    path = args.rig or default_imu_rig_path()
    if path.is_file():
        _check_toml(path)  # a broken file is reported as broken, not as the wrong kind
    if path.is_file() and not is_imu_rig(path):
        raise RigError(f"{path}: [rig] kind: not an IMU-bench rig; `rotorbench calibrate` "
                       "needs a rig file with [rig] kind = \"imu\" (see fixtures/rigs/"
                       "sim-imu.toml)")
    rig = load_imu_rig(path)
    return rig.with_seed(args.seed) if args.seed is not None else rig


def _check_toml(path) -> None:
    try:
        with path.open("rb") as fh:
            tomllib.load(fh)
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise RigError(f"{path}: not valid TOML: {exc}") from None
    except OSError as exc:
        raise RigError(f"{path}: cannot read rig file: {exc.strerror or exc}") from None


def run_on_rig(args: argparse.Namespace) -> int:
    rig = _load(args)
    options = HexapodRunOptions(tick_s=args.tick, realtime=bool(args.realtime),
                                trajectory_rate_hz=rig.hexapod.trajectory_rate_hz)
    seqs = paper_a_sequences(rig.imu.value("rate_hz"), quick=args.quick)
    plans = plans_for(rig, seqs)
    if args.dry_run:
        print(f"rig {rig.name} ({rig.path}); pivot {vec(rig.hexapod.pivot_m, '{:g}')} m; "
              f"{len(plans)} stages, {sum(p.duration_s for p in plans):.1f} s")
        for plan in plans:
            print()
            print(format_plan(plan))
        return 0
    _check_out(args)
    check_writable(args.runs, "--runs", folder=True)
    session = new_run_id("calibration")
    out = args.out or args.runs / f"{session}.json"
    try:
        args.runs.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise RigError(f"--runs {args.runs}: cannot create the run folder "
                       f"({exc.strerror or exc})") from None
    run = _run_with_progress(rig, plans, args, options, session)
    console = Console()
    _print_stages(run, console)
    if not run.complete:
        failed = run.stages[-1].result if run.stages else None
        print(f"calibration stopped at stage {len(run.stages)}/{run.planned}: "
              f"{failed.status + ': ' + failed.reason if failed else 'no stage ran'}; "
              "no calibration written", file=sys.stderr)
        return 1
    log_path = collect_log([s.run_dir for s in run.stages], args.runs / f"{session}.parquet")
    print(f"wrote {log_path}", file=sys.stderr)
    df = load_calibration_log(log_path)
    cal = calibrate_frame(df, rig.imu.measured_mounting_deg, rig.imu.value("gyro_range_rad_s"),
                          rig.imu.value("acc_range_m_s2"), max_lag_s=0.5)
    cal.source = str(log_path)
    print_calibration(cal, console)
    if run.truth is not None:
        _print_truth(cal, run.truth, console)
    finish(cal, df, args, out, str(log_path))
    return 0


def _run_with_progress(rig, plans: list[HexapodPlan], args: argparse.Namespace,
                       options: HexapodRunOptions, session: str) -> CalibrationRun:
    total = sum(p.duration_s for p in plans)
    offsets = np.concatenate([[0.0], np.cumsum([p.duration_s for p in plans])])
    progress = Progress(TextColumn("{task.description}"), BarColumn(),
                        TextColumn("{task.completed:6.1f}/{task.total:.1f} s rig time"),
                        TimeElapsedColumn(), console=err_console())
    task = progress.add_task("calibration", total=total)
    stage = {"i": 0}
    stop = threading.Event()

    def on_stage(i: int, plan: HexapodPlan) -> None:
        stage["i"] = i
        progress.update(task, completed=offsets[i],
                        description=f"{i + 1}/{len(plans)} {plan.sequence.name}")

    def on_progress(t: float, _total: float, seg: HexapodSegment) -> None:
        i = stage["i"]
        progress.update(task, completed=min(offsets[i] + t, total),
                        description=f"{i + 1}/{len(plans)} {plans[i].sequence.name} "
                                    f"[{seg.phase}: {seg.label}]")

    meta = {"command_line": ["rotorbench", *sys.argv[1:]], "calibration_session": session,
            "quick": bool(args.quick)}
    with say_where_an_interrupted_run_went("calibration stage", "hexapod stopped"), \
            progress, _sigterm_as_interrupt(stop), erase_on_user_error(progress):
        return run_calibration(rig, args.runs, quick=args.quick, options=options,
                               sequences=[p.sequence for p in plans], on_stage=on_stage,
                               on_progress=on_progress, stop_event=stop, extra_meta=meta)


def _print_stages(run: CalibrationRun, console: Console) -> None:
    t = Table(title="calibration stages (one recorded run each)")
    for col in ("stage", "status", "rows", "rig time (s)", "run folder"):
        t.add_column(col)
    for s in run.stages:
        r = s.result
        t.add_row(s.plan.sequence.name, f"{r.status}: {r.reason}", str(r.rows),
                  f"{r.t_end_s:.1f}", str(s.run_dir))
    console.print(t)


def _rel(a, b) -> float:
    a, b = np.asarray(a, float), np.asarray(b, float)
    return float(np.linalg.norm(a - b) / np.linalg.norm(b))


def _print_truth(cal: Calibration, truth: dict, console: Console) -> None:
    """The estimates against the simulator's hidden truth (simulated rigs only)."""
    t = Table(title="against the simulated IMU's truth")
    for col in ("quantity", "estimated", "true", "error"):
        t.add_column(col)
    t.add_row("K_ω", "", "", f"{100 * _rel(cal.k_gyro, truth['k_gyro']):.3f} % (rel. Frobenius)")
    t.add_row("K_a", "", "", f"{100 * _rel(cal.k_acc, truth['k_acc']):.3f} % (rel. Frobenius)")
    r_true = np.asarray(truth["lever_arm_from_pivot_m"])
    err = (np.asarray(cal.lever_arm_m) - r_true) * 1e3
    t.add_row("lever arm R (m)", vec(cal.lever_arm_m, "{:+.4f}"), vec(r_true, "{:+.4f}"),
              vec(err, "{:+.2f}") + " mm")
    z = (np.asarray(cal.gyro_bias_rad_s) - truth["gyro_bias_rad_s"]) / \
        np.asarray(cal.gyro_bias_stderr_rad_s)
    t.add_row("gyro bias (rad/s)", vec(cal.gyro_bias_rad_s, "{:+.5f}"),
              vec(truth["gyro_bias_rad_s"], "{:+.5f}"), vec(z, "{:+.2f}") + " std. err.")
    t.add_row("time offset (ms)", f"{cal.time_offset_s * 1e3:.2f}",
              f"{truth['clock_offset_s'] * 1e3:.2f}",
              f"{(cal.time_offset_s - truth['clock_offset_s']) * 1e3:+.2f} ms")
    psi = cal.decomposition.get("gyro", {}).get("euler_deg", [math.nan] * 3)
    t.add_row("mounting φ, θ, ψ (deg, from K_ω)", vec(psi, "{:.3f}"),
              vec(truth["mounting_deg"], "{:.3f}"), "")
    console.print(t)
