"""``rotorbench calibrate``: IMU calibration on a hexapod (Paper A): on the rig, from a log,
and apply.

    rotorbench calibrate [--rig FILE] [--out cal.json] [--quick] [--runs DIR] [--dry-run]
    rotorbench calibrate --simulate-log sim.parquet          # write a simulated log
    rotorbench calibrate --from-log sim.parquet --out cal.json [--figures DIR]
    rotorbench calibrate apply --cal cal.json LOG --out corrected.parquet

On the rig (default: the simulated IMU bench ``bench/data/rigs/sim-imu.toml``) every Paper A
stage runs as its own recorded run (``bench.jobs.calibration_stages``); the stages' samples are
joined into one calibration log next to the runs and calibrated like ``--from-log``.
"""

from __future__ import annotations

import argparse
import math
import sys
import tomllib
from pathlib import Path

from rich.console import Console
from rich.table import Table

from analysis.errors import LogError
from analysis.imu_calibration import (
    Calibration,
    apply_to_frame,
    load_calibration,
    save_calibration,
)
from analysis.imu_log import load_calibration_log, load_imu_log, write_table
from bench.cli_args.option_values import refuse_unused, seed_arg
from bench.cli_args.store_args import add_store_args, publish_runs, recording_store
from bench.engine.recorder import new_run_id
from bench.errors import RigError
from bench.figures.calibration_report import mat, show_calibration, show_stages, show_truth, vec
from bench.jobs.calibration_stages import calibrate_frame, collect_log, plans_for
from bench.jobs.run_progress import JobOutput, run_calibration_with_progress
from bench.paths.outputs import check_writable
from bench.plan_runner.runner import HexapodRunOptions
from bench.plans.calibration_sequences import format_plan, paper_a_sequences
from bench.rig.rig import default_imu_rig_path, is_imu_rig, load_imu_rig


class _OptionalAction(argparse.HelpFormatter):
    """Usage shows the sub-action as optional (``[ACTION ...]``): ``calibrate`` alone runs
    on the rig, ``calibrate apply`` is the one sub-action (argparse always writes it as
    required)."""

    def _format_args(self, action: argparse.Action, default_metavar: str) -> str:
        text = super()._format_args(action, default_metavar)
        if action.nargs == argparse.PARSER and not action.required:
            return f"[{text}]"
        return text


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "calibrate", formatter_class=_OptionalAction,
        help="IMU calibration on a hexapod (Paper A): from a log, or apply",
        description="Calibrate an IMU from a hexapod calibration log (CSV/Parquet), write a "
                    "simulated log, or apply a calibration to any IMU log.")
    p.add_argument("--from-log", type=Path, metavar="FILE",
                   help="calibration log (.csv/.parquet) with phases bias, gyro, acc, "
                        "lever_x/y/z and optionally verify")
    p.add_argument("--out", type=Path, metavar="cal.json", help="write the calibration JSON")
    p.add_argument("--figures", type=Path, metavar="DIR",
                   help="write Fig. A.7-A.10 style PNGs of the verification motion")
    p.add_argument("--mounting-deg", type=float, nargs=3, metavar=("PHI", "THETA", "PSI"),
                   help="measured IMU mounting angles (A.15) to compare K's rotation with")
    p.add_argument("--gyro-range-dps", type=float, default=300.0,
                   help="gyro range for %% of range (default: ADIS16400, 300 °/s)")
    p.add_argument("--acc-range-g", type=float, default=18.0,
                   help="accelerometer range for %% of range (default: ADIS16400, 18 g)")
    p.add_argument("--max-lag", type=float, default=0.5, metavar="S",
                   help="largest hexapod-IMU time offset searched (s, default 0.5)")
    p.add_argument("--simulate-log", type=Path, metavar="OUT",
                   help="write a simulated calibration log (ADIS16400 on the simulated "
                        "hexapod, Paper A protocol) and print its true parameters")
    p.add_argument("--short", action="store_true",
                   help="with --simulate-log: shortened protocol (fast, same stages)")
    p.add_argument("--seed", type=seed_arg, default=None,
                   help="random seed (--simulate-log: default 0; rig: the rig file's seed)")
    p.add_argument("--rig", type=Path, metavar="FILE",
                   help="IMU-bench rig file ([rig] kind = \"imu\"); default: the simulated "
                        "bench bench/data/rigs/sim-imu.toml")
    p.add_argument("--quick", action="store_true",
                   help="on the rig: shortened stages (3000-sample hold, 0.02 Hz rotation, "
                        "20 s lever-arm and 30 s verification motions)")
    p.add_argument("--runs", type=Path, default=Path("runs"), metavar="DIR",
                   help="on the rig: root of the run folders and runs.sqlite (default ./runs)")
    p.add_argument("--dry-run", action="store_true",
                   help="on the rig: print every stage's steps, times and motion peaks; "
                        "touch no device")
    add_store_args(p, records=True)
    p.add_argument("--tick", type=float, default=0.05,
                   help="on the rig: read period in seconds (default 0.05)")
    p.add_argument("--realtime", action="store_true",
                   help="on the rig: pace a simulated rig to the wall clock")
    sub = p.add_subparsers(dest="calibrate_action", metavar="ACTION")
    a = sub.add_parser("apply", help="correct an IMU log with a calibration JSON")
    a.add_argument("--cal", type=Path, required=True, metavar="cal.json")
    a.add_argument("log", type=Path, metavar="LOG")
    a.add_argument("--out", type=Path, required=True, metavar="FILE",
                   dest="apply_out", help="corrected log (.csv/.parquet)")
    p.set_defaults(func=handler)


#: the options of each way to run the command (an option of another way is refused: it
#: would be ignored)
_RIG_ONLY = ("--rig", "--quick", "--runs", "--dry-run", "--tick", "--realtime", "--store",
             "--spool", "--bench")
_CALIBRATION = ("--out", "--figures", "--mounting-deg", "--gyro-range-dps", "--acc-range-g",
                "--max-lag")


def handler(args: argparse.Namespace) -> int:
    if getattr(args, "calibrate_action", None) == "apply":
        refuse_unused(args, ("--from-log", "--simulate-log", "--short", "--seed", *_RIG_ONLY,
                             "--figures", "--mounting-deg", "--gyro-range-dps",
                             "--acc-range-g", "--max-lag"),
                      "with calibrate apply")
        return _apply(args)
    if args.simulate_log is not None:
        refuse_unused(args, ("--from-log", *_RIG_ONLY, *_CALIBRATION),
                      "with --simulate-log (it writes the simulated log and calibrates "
                      "nothing; calibrate from it with a second command)")
        return _simulate(args)
    refuse_unused(args, ("--short",), "without --simulate-log (--quick shortens the stages "
                                      "on the rig)")
    if args.from_log is None:
        return run_on_rig(args)
    refuse_unused(args, ("--seed", *_RIG_ONLY), "with --from-log")
    _check_out(args)
    df = load_calibration_log(args.from_log)
    mounting = tuple(args.mounting_deg) if args.mounting_deg else None
    cal = calibrate_frame(df, mounting, math.radians(args.gyro_range_dps),
                          args.acc_range_g * 9.80665, args.max_lag)
    show_calibration(cal, Console().print)
    finish(cal, df, args, args.out, str(args.from_log))
    return 0


def _check_out(args: argparse.Namespace) -> None:
    if args.out is not None:
        check_writable(args.out, "--out", folder=False, inputs=(args.from_log,))
    if args.figures is not None:
        check_writable(args.figures, "--figures", folder=True)
    for flag, value in (("--gyro-range-dps", args.gyro_range_dps),
                        ("--acc-range-g", args.acc_range_g), ("--max-lag", args.max_lag)):
        if not (math.isfinite(value) and value > 0):
            raise LogError(f"{flag}: expected a number > 0, got {value:g}")
    if args.mounting_deg and not all(math.isfinite(v) for v in args.mounting_deg):
        raise LogError("--mounting-deg: expected three finite angles in degrees, got "
                       + " ".join(f"{v:g}" for v in args.mounting_deg))


def finish(cal: Calibration, df, args: argparse.Namespace, out: Path | None, source: str) -> None:
    """Figures (``--figures``) and the calibration JSON (atomic)."""
    if args.figures is not None:
        from analysis.imu_figures import verification_figures

        if cal.verification_rms is None:
            raise LogError(f"{source}: --figures needs a 'verify' phase in the log")
        for path in verification_figures(cal, df, args.figures):
            print(f"wrote {path}", file=sys.stderr)
    if out is not None:
        out.parent.mkdir(parents=True, exist_ok=True)  # as the other commands do
        save_calibration(cal, out)
        print(f"wrote {out}", file=sys.stderr)


def _apply(args: argparse.Namespace) -> int:
    check_writable(args.apply_out, "--out", folder=False, inputs=(args.log, args.cal))
    cal = load_calibration(args.cal)
    df = load_imu_log(args.log)
    out = apply_to_frame(cal, df)
    args.apply_out.parent.mkdir(parents=True, exist_ok=True)
    write_table(out, args.apply_out)
    print(f"wrote {args.apply_out} ({len(out)} rows; time offset "
          f"{cal.time_offset_s * 1e3:.2f} ms applied)", file=sys.stderr)
    return 0


def _simulate(args: argparse.Namespace) -> int:
    import pandas as pd

    from drivers.hexapod_motions import paper_a_protocol
    from drivers.sim.imu import ADIS16400
    from drivers.sim.imu_calibration_log import simulate_calibration_log

    if args.simulate_log.suffix.lower() not in (".csv", ".parquet"):
        raise LogError(f"{args.simulate_log}: simulated log must end in .csv or .parquet")
    check_writable(args.simulate_log, "--simulate-log", folder=False)
    m = ADIS16400
    seed = 0 if args.seed is None else args.seed
    cols = simulate_calibration_log(m, paper_a_protocol(m.rate_hz, short=args.short),
                                    seed=seed)
    args.simulate_log.parent.mkdir(parents=True, exist_ok=True)
    write_table(pd.DataFrame(cols), args.simulate_log, float_format="%.9g")
    console = Console()
    console.print(f"wrote {args.simulate_log}: {len(cols['t_s'])} rows at {m.rate_hz:g} Hz "
                  f"(seed {seed})")
    t = Table(title="true parameters of the simulated IMU")
    t.add_column("parameter")
    t.add_column("value")
    t.add_row("mounting φ, θ, ψ (deg)", vec(m.mounting_deg, "{:.2f}"))
    t.add_row("lever arm R (m)", vec(m.lever_arm_m, "{:.3f}"))
    t.add_row("gyro bias (rad/s)", vec(m.gyro_bias_rad_s, "{:.4f}"))
    t.add_row("clock offset (ms)", f"{m.clock_offset_s * 1e3:.2f}")
    t.add_row("K_ω", mat(m.k_gyro()))
    t.add_row("K_a", mat(m.k_acc()))
    console.print(t)
    return 0


# --- on the rig ------------------------------------------------------------------------------
def _load(args: argparse.Namespace):
    path = args.rig or default_imu_rig_path()
    if path.is_file():
        _check_toml(path)  # a broken file is reported as broken, not as the wrong kind
    if path.is_file() and not is_imu_rig(path):
        raise RigError(f"{path}: [rig] kind: not an IMU-bench rig; `rotorbench calibrate` "
                       "needs a rig file with [rig] kind = \"imu\" (see bench/data/rigs/"
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
    store = recording_store(args, out_attr="runs", warn=_to_stderr)  # a lab store spools
    rig = _load(args)
    hexapod, imu = rig.hexapod, rig.imu
    assert hexapod is not None and imu is not None  # an IMU rig has both (load_imu_rig)
    options = HexapodRunOptions(tick_s=args.tick, realtime=bool(args.realtime),
                                trajectory_rate_hz=hexapod.trajectory_rate_hz)
    seqs = paper_a_sequences(imu.value("rate_hz"), quick=args.quick)
    plans = plans_for(rig, seqs)
    if args.dry_run:
        print(f"rig {rig.name} ({rig.path}); pivot {vec(hexapod.pivot_m, '{:g}')} m; "
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
    run = run_calibration_with_progress(
        rig, plans, args.runs, quick=args.quick, options=options,
        extra_meta={"calibration_session": session, "quick": bool(args.quick)},
        output=JobOutput(out=print, err=_to_stderr))
    console = Console()
    show_stages(run, console.print)
    if not run.complete:
        failed = run.stages[-1].result if run.stages else None
        print(f"calibration stopped at stage {len(run.stages)}/{run.planned}: "
              f"{failed.status + ': ' + failed.reason if failed else 'no stage ran'}; "
              "no calibration written", file=sys.stderr)
        publish_runs(store, tell=print)
        return 1
    log_path = collect_log([s.run_dir for s in run.stages], args.runs / f"{session}.parquet")
    print(f"wrote {log_path}", file=sys.stderr)
    df = load_calibration_log(log_path)
    cal = calibrate_frame(df, imu.measured_mounting_deg, imu.value("gyro_range_rad_s"),
                          imu.value("acc_range_m_s2"), max_lag_s=0.5)
    cal.source = str(log_path)
    show_calibration(cal, console.print)
    if run.truth is not None:
        show_truth(cal, run.truth, console.print)
    finish(cal, df, args, out, str(log_path))
    publish_runs(store, tell=print)
    return 0


def _to_stderr(line: str) -> None:
    print(line, file=sys.stderr, flush=True)
