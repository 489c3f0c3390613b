"""``rotorbench calibrate``: IMU calibration on a hexapod (Paper A): on the rig, from a log,
and apply.

    rotorbench calibrate [--rig FILE] [--out cal.json] [--quick] [--runs DIR] [--dry-run]
    rotorbench calibrate --simulate-log sim.parquet          # write a simulated log
    rotorbench calibrate --from-log sim.parquet --out cal.json [--figures DIR]
    rotorbench calibrate apply --cal cal.json LOG --out corrected.parquet

On the rig (default: the simulated IMU bench ``fixtures/rigs/sim-imu.toml``) every Paper A
stage runs as its own recorded run (``bench.calibration_session``); the stages' samples are
joined into one calibration log next to the runs and calibrated like ``--from-log``.
"""

from __future__ import annotations

import argparse
import math
import sys
import warnings
from pathlib import Path

import numpy as np
from rich.console import Console
from rich.table import Table

from analysis.errors import LogError
from analysis.imu_calibration import (
    Calibration,
    apply_to_frame,
    calibrate,
    load_calibration,
    save_calibration,
)
from analysis.imu_log import load_calibration_log, load_imu_log, write_table
from bench.cli_support import check_writable

_XYZ = ("x", "y", "z")


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "calibrate", help="IMU calibration on a hexapod (Paper A): from a log, or apply",
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
    p.add_argument("--seed", type=int, default=None,
                   help="random seed (--simulate-log: default 0; rig: the rig file's seed)")
    p.add_argument("--rig", type=Path, metavar="FILE",
                   help="IMU-bench rig file ([rig] kind = \"imu\"); default: the simulated "
                        "bench fixtures/rigs/sim-imu.toml")
    p.add_argument("--quick", action="store_true",
                   help="on the rig: shortened stages (3000-sample hold, 0.02 Hz rotation, "
                        "20 s lever-arm and 30 s verification motions)")
    p.add_argument("--runs", type=Path, default=Path("runs"), metavar="DIR",
                   help="on the rig: root of the run folders and runs.sqlite (default ./runs)")
    p.add_argument("--dry-run", action="store_true",
                   help="on the rig: print every stage's steps, times and motion peaks; "
                        "touch no device")
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


def handler(args: argparse.Namespace) -> int:
    if getattr(args, "calibrate_action", None) == "apply":
        return _apply(args)
    if args.simulate_log is not None:
        return _simulate(args)
    if args.from_log is None:
        from bench.commands._calibrate_rig import run_on_rig

        return run_on_rig(args)
    _check_out(args)
    df = load_calibration_log(args.from_log)
    mounting = tuple(args.mounting_deg) if args.mounting_deg else None
    cal = calibrate_frame(df, mounting, math.radians(args.gyro_range_dps),
                          args.acc_range_g * 9.80665, args.max_lag)
    print_calibration(cal, Console())
    finish(cal, df, args, args.out, str(args.from_log))
    return 0


def _check_out(args: argparse.Namespace) -> None:
    if args.out is not None:
        check_writable(args.out, "--out", folder=False, make_parents=False)
    if args.figures is not None:
        check_writable(args.figures, "--figures", folder=True)
    for flag, value in (("--gyro-range-dps", args.gyro_range_dps),
                        ("--acc-range-g", args.acc_range_g), ("--max-lag", args.max_lag)):
        if not (math.isfinite(value) and value > 0):
            raise LogError(f"{flag}: expected a number > 0, got {value:g}")


def calibrate_frame(df, mounting: tuple[float, float, float] | None, gyro_range_rad_s: float,
                    acc_range_m_s2: float, max_lag_s: float) -> Calibration:
    """Paper A's stages on a validated log; warnings are kept in ``cal.warnings``."""
    with warnings.catch_warnings():  # warnings are kept in cal.warnings and printed below
        warnings.simplefilter("ignore")
        return calibrate(df, measured_mounting_deg=mounting, gyro_range_rad_s=gyro_range_rad_s,
                         acc_range_m_s2=acc_range_m_s2, max_lag_s=max_lag_s)


def finish(cal: Calibration, df, args: argparse.Namespace, out: Path | None, source: str) -> None:
    """Figures (``--figures``) and the calibration JSON (atomic)."""
    if args.figures is not None:
        from analysis.imu_figures import verification_figures

        if cal.verification_rms is None:
            raise LogError(f"{source}: --figures needs a 'verify' phase in the log")
        for path in verification_figures(cal, df, args.figures):
            print(f"wrote {path}", file=sys.stderr)
    if out is not None:
        save_calibration(cal, out)
        print(f"wrote {out}", file=sys.stderr)


def _apply(args: argparse.Namespace) -> int:
    check_writable(args.apply_out, "--out", folder=False, make_parents=False)
    cal = load_calibration(args.cal)
    df = load_imu_log(args.log)
    out = apply_to_frame(cal, df)
    write_table(out, args.apply_out)
    print(f"wrote {args.apply_out} ({len(out)} rows; time offset "
          f"{cal.time_offset_s * 1e3:.2f} ms applied)", file=sys.stderr)
    return 0


def _simulate(args: argparse.Namespace) -> int:
    from drivers.hexapod_motions import paper_a_protocol
    from drivers.sim.imu import ADIS16400
    from drivers.sim.imu_calibration_log import simulate_calibration_log, write_calibration_log

    if args.simulate_log.suffix.lower() not in (".csv", ".parquet"):
        raise LogError(f"{args.simulate_log}: simulated log must end in .csv or .parquet")
    check_writable(args.simulate_log, "--simulate-log", folder=False, make_parents=False)
    m = ADIS16400
    seed = 0 if args.seed is None else args.seed
    cols = simulate_calibration_log(m, paper_a_protocol(m.rate_hz, short=args.short),
                                    seed=seed)
    write_calibration_log(args.simulate_log, cols)
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


def vec(v, fmt: str) -> str:
    return "[" + ", ".join(fmt.format(float(x)) for x in v) + "]"


def mat(k) -> str:
    return "\n".join(vec(row, "{:+.4f}") for row in np.asarray(k))


def print_calibration(cal: Calibration, console: Console) -> None:
    s = Table(title="IMU calibration (Paper A)")
    s.add_column("quantity")
    s.add_column("value")
    bias = ", ".join(f"{b:+.5f} ± {e:.5f}" for b, e in
                     zip(cal.gyro_bias_rad_s, cal.gyro_bias_stderr_rad_s, strict=True))
    s.add_row("gyro bias (A.12), rad/s", bias)
    s.add_row("accelerometer bias, m/s²", vec(cal.acc_bias_m_s2, "{:+.4f}"))
    s.add_row("time offset hexapod→IMU", f"{cal.time_offset_s * 1e3:.2f} ms")
    s.add_row(f"K_ω (A.13), cond {cal.conditioning.get('gyro', float('nan')):.2f}",
              mat(cal.k_gyro))
    s.add_row(f"K_a (A.14), cond {cal.conditioning.get('acc', float('nan')):.2f}",
              mat(cal.k_acc))
    s.add_row("lever arm R, m", vec(cal.lever_arm_m, "{:+.4f}"))
    console.print(s)

    d = Table(title="K split into rotation, scale, non-orthogonality (A.15-A.16)",
              caption=cal.decomposition.get("convention", ""))
    for col in ("sensor", "φ, θ, ψ (deg)", "scale", "non-orth xy, xz, yz (deg)",
                "vs measured (deg)"):
        d.add_column(col)
    for name in ("gyro", "acc"):
        p = cal.decomposition.get(name, {})
        if not p:
            continue
        vs = p.get("rotation_vs_measured_deg")
        d.add_row(name, vec(p["euler_deg"], "{:.3f}"), vec(p["scale"], "{:.4f}"),
                  vec(p["nonorthogonality_deg"], "{:+.3f}"), "-" if vs is None else f"{vs:.3f}")
    console.print(d)

    est = cal.lever_arm_estimates
    la = Table(title="Lever arm estimates from α (A.11), m (Table A.1 layout)")
    for col in ("rotation axis", "R_x", "R_y", "R_z"):
        la.add_column(col)
    for ax in _XYZ:
        row = est.get("table_a1_alpha_m", {}).get(ax, {})
        la.add_row(f"ω_{ax}", *(f"{row[c]:+.4f}" if c in row else "-" for c in _XYZ))
    la.add_row("final (mean)", *(f"{v:+.4f}" for v in cal.lever_arm_m))
    la.add_row("agreement |Δ|", *(f"{v * 1e3:.2f} mm" for v in est.get("agreement_m", [])))
    for ax in _XYZ:
        row = est.get("omega2_m", {}).get(ax, {})
        la.add_row(f"ω_{ax} (ω² term)", *(f"{row[c]:+.3f}" if c in row else "-" for c in _XYZ))
    console.print(la)

    v = cal.verification_rms
    if v is None:
        console.print("no 'verify' phase in the log: verification RMS not computed")
    else:
        t = Table(title=f"Verification RMS (A.19) on the independent motion, "
                        f"{v['samples']} samples (Table A.2)")
        for col in ("signal", "raw", "corrected", "% of range", "% of peak", "Table A.2"):
            t.add_column(col)
        for kind, unit, pk in (("acc_m_s2", "m/s²", "acc_pct_peak"),
                               ("gyro_rad_s", "rad/s", "gyro_pct_peak")):
            short = "a" if kind.startswith("acc") else "ω"
            pct = v["acc_pct_range" if short == "a" else "gyro_pct_range"]["corrected"]
            for i, ax in enumerate(_XYZ):
                t.add_row(f"{short}_{ax} ({unit})", f"{v[kind]['raw'][i]:.4f}",
                          f"{v[kind]['corrected'][i]:.4f}", f"{pct[i]:.3f} %",
                          f"{v[pk][i]:.2f} %", f"{v['table_a2'][kind][i]:.4f}")
        console.print(t)
    for w in cal.warnings:
        console.print(f"[yellow]warning:[/yellow] {w}")
