"""``rotorbench report RUN [RUN ...] [--out DIR]``: Table C.1, static curves, Step 2
validation and their figures for a set of runs.

Every run with a vibration column (a stand's logged level or accelerometer axes) gets
vibration against speed (a figure and a line of the vibration table), and a spectrum with
the rotor and blade-pass frequencies marked where its sampling allows one
(``analysis.vibration``).

Step runs are fitted (Table C.1, Fig. C.9-C.12), sweeps and imported stand logs give the
static curves (Fig. C.13-C.14), and Step 2 runs are simulated with the fitted models of
the Step 1 run of the same ESC mode (Fig. C.16-C.19). The folder is built beside ``DIR``
and renamed into place when complete; an earlier report there is replaced only when
it holds nothing but the report's own files (its manifest).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import shutil
from pathlib import Path
from typing import Any

from rich.console import Console

from bench.cli_args.store_args import add_store_args, run_folder_arg
from bench.errors import RigError
from bench.paths.outputs import check_writable
from bench.paths.owned_folder import refuse_foreign, write_manifest

G0 = 9.80665
#: What a report folder held before its manifest (:mod:`bench.paths.owned_folder`).
REPORT_NAMES = ("report.json", "table_c1.csv", "static_curves.csv", "validation.csv",
                "steps.png", "static_*.png", "validation_*.png")


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "report", help="tables (Table C.1, static curves, Step 2 validation) and figures",
        description="Fits every step run (Table C.1), the static curves of every sweep or "
                    "imported log (Fig. C.13-C.14) and simulates the fitted models on every "
                    "Step 2 run (Fig. C.16-C.19); writes PNG figures and CSV tables.")
    p.add_argument("runs", type=Path, nargs="+", metavar="RUN",
                   help="run folders, or run ids of --store")
    add_store_args(p)
    p.add_argument("--out", type=Path, default=None,
                   help="output folder (default: ./report-<first run id>)")
    p.add_argument("--kv", type=float, default=None, help="motor K_V (rpm/V) for (C.3)")
    p.add_argument("--r-ohm", type=float, default=None, help="winding resistance (ohm)")
    p.add_argument("--j-kg-m2", type=float, default=None, help="inertia motor + propeller")
    p.add_argument("--blades", type=int, default=None,
                   help="propeller blades for the blade-pass frequency (default: the "
                        "simulated rig's vibration_blades, else 2)")
    p.set_defaults(func=handler)


def _motor(args: argparse.Namespace, records: list[Any]):
    from analysis.static_curves import TABLE_C2, MotorParams

    given = (args.kv, args.r_ohm, args.j_kg_m2)
    if all(v is not None for v in given):
        for flag, value in zip(("--kv", "--r-ohm", "--j-kg-m2"), given, strict=True):
            if not (math.isfinite(value) and value > 0):
                raise RigError(f"{flag}: expected a number > 0, got {value:g}")
        return MotorParams(args.kv, args.r_ohm, args.j_kg_m2)
    if any(v is not None for v in given):
        raise RigError("--kv, --r-ohm and --j-kg-m2 go together")
    # Paper C's hardware (the default sim rig): Table C.2's datasheet/measured inputs
    if any(r.components.get("motor") == "dji-2212-920kv" for r in records):
        return TABLE_C2
    return None


def build(args: argparse.Namespace, out: Path, console: Console) -> dict[str, Any]:
    from analysis.errors import LogError
    from analysis.figures import plot_static, plot_steps, plot_validation
    from analysis.report import OUTPUT_DELAY, Table, output_delay_line, table_c1, write_csv
    from analysis.run_record import read_run
    from analysis.static_curves import fit_static_run, from_parameters
    from analysis.step_response import fit_run
    from analysis.validation import validate_run

    records = [read_run(p) for p in args.runs]
    motor = _motor(args, records)
    if args.blades is not None and not 1 <= args.blades <= 12:
        raise RigError(f"--blades: expected a whole number 1-12, got {args.blades}")
    fits, statics, step2s, notes = [], [], [], []
    for rec in records:
        kind = str(rec.meta.get("kind", ""))
        label = str(rec.components.get("esc_mode") or rec.id)
        if kind in ("sweep", "import"):
            try:
                statics.append((rec, fit_static_run(rec)))
                notes.extend(f"{rec.id}: {n}" for n in statics[-1][1].notes)
            except LogError as exc:
                notes.append(f"{rec.id}: no static curves ({exc})")
        elif kind == "step2":
            step2s.append((rec, label))
        else:
            try:
                fits.append((rec, label, fit_run(rec)))
                notes.extend(f"{rec.id}: {n}" for n in fits[-1][2].notes)
            except LogError as exc:
                notes.append(f"{rec.id}: no step fit ({exc})")
    summary: dict[str, Any] = {"runs": [str(r.path) for r in records], "notes": notes}
    for rec in records:  # runs with missed or late samples are marked (run.json "drops")
        summary.setdefault("dropped_samples", {})[rec.id] = rec.meta.get("dropped_samples")
        if rec.meta.get("dropped_samples"):
            notes.append(f"{rec.id}: {rec.meta['dropped_samples']} samples missed or late "
                         f"(longest gap {rec.meta.get('longest_gap_s') or 0:.3f} s; run.json "
                         "drops)")
        delay = output_delay_line(rec.meta)
        if delay is not None:
            summary.setdefault(OUTPUT_DELAY, {})[rec.id] = rec.meta[OUTPUT_DELAY]
            notes.append(f"{rec.id}: {delay}")
        if rec.meta.get("link_errors"):
            notes.append(f"{rec.id}: {rec.meta['link_errors']} frames lost on device links "
                         "(run.json drops.<role>.link_errors)")

    tau_par = None
    if motor is not None:
        d = motor.d_a_s_rad
        for _, s in statics:  # D of Fig. C.5: slope of the measured current at hover
            w = float(s.omega_for_thrust(0.25 * G0)) if s.thrust_poly is not None else math.nan
            if math.isfinite(w) and s.current_poly is not None:
                d = s.damping_at(w)
                break
        if math.isfinite(d):
            tau_par = from_parameters(motor, d)[0]
            summary["from_parameters"] = {"tau_ms": tau_par * 1e3, "damping_a_s_rad": d}
    if fits:
        tc1 = table_c1([(lbl, f) for _, lbl, f in fits], tau_par)
        console.print(tc1.to_rich())
        write_csv(tc1, out / "table_c1.csv")
        plot_steps([(lbl, f) for _, lbl, f in fits], out / "steps.png")
        summary["fits"] = {f"{lbl} ({rec.id})": {k: v for k, v in f.summary().items()
                                                 if k != "edges"} for rec, lbl, f in fits}
    if statics:
        rows = []
        for rec, s in statics:
            plot_static(s, out / f"static_{rec.id}.png", title=f"Static curves: {rec.id}")
            sm = s.summary()
            rows.append((rec.id, sm["k_f_n_s2"], sm["moment_constant_m"], sm["rpm_max"],
                         sm["thrust_rms_n"], sm["thrust_rms_binned_n"], sm["current_rms_a"],
                         sm["current_rms_binned_a"]))
            summary.setdefault("static", {})[rec.id] = sm
        ts = Table("Static curves (Fig. C.13-C.14)",
                   ("run", "k_f [N s2]", "torque/thrust [m]", "rpm max", "thrust rms [N]",
                    "thrust rms of binned medians [N]", "current rms [A]",
                    "current rms of binned medians [A]"), tuple(rows),
                   note="rms: residual of the raw samples to the fitted curve; of binned "
                        "medians: of the speed-bin medians the curve was fitted to")
        console.print(ts.to_rich())
        write_csv(ts, out / "static_curves.csv")
    if step2s:
        rows = []
        static = next((s for _, s in statics if s.current_poly is not None
                       and s.thrust_poly is not None), None)
        for rec, label in step2s:
            fit = next((f for _, lbl, f in fits if lbl == label), None)
            if fit is None:
                notes.append(f"{rec.id}: no Step 1 fit of ESC mode {label} to validate")
                continue
            v = validate_run(rec, fit, static, motor)
            plot_validation(v, out / f"validation_{rec.id}.png",
                            title=f"Step 2, {label}: RMS error first order "
                                  f"{v.rms_first_order_pct:.1f} %, nonlinear load "
                                  f"{v.rms_nonlinear_pct:.1f} % of the band")
            rows.append((label, v.rms_first_order / G0 * 1e3, v.rms_first_order_pct,
                         v.rms_nonlinear / G0 * 1e3, v.rms_nonlinear_pct))
        if rows:
            tv = Table("Step 2 validation (Paper C section 5)",
                       ("ESC", "first order [g]", "[% band]", "nonlinear load [g]",
                        "[% band]"), tuple(rows))
            console.print(tv.to_rich())
            write_csv(tv, out / "validation.csv")
            summary["validation"] = [dict(zip(tv.columns, r, strict=True)) for r in rows]
    _vibration(args, records, out, console, notes, summary)
    for n in notes:
        console.print(f"note: {n}")
    return summary


def _blades(args: argparse.Namespace, rec: Any) -> tuple[int, str]:
    """The blade count and where it came from: --blades, the sim rig's, or assumed 2."""
    if args.blades is not None:
        return args.blades, "--blades"
    sensors = ((rec.meta.get("rig") or {}).get("sim") or {}).get("sensors") or {}
    if "vibration_blades" in sensors:
        return int(sensors["vibration_blades"]), "rig"
    return 2, "assumed"


def _vibration(args: argparse.Namespace, records: list[Any], out: Path, console: Console,
               notes: list[str], summary: dict[str, Any]) -> None:
    """Vibration against speed for every run that logs it; a spectrum where the rate allows."""
    from analysis.errors import LogError
    from analysis.report import Table, write_csv
    from analysis.vibration import vibration_spectrum, vibration_vs_speed
    from analysis.vibration_figures import plot_vibration_spectrum, plot_vibration_speed

    rows = []
    for rec in records:
        curve = vibration_vs_speed(rec.samples)
        if curve is None:
            continue
        plot_vibration_speed(curve, out / f"vibration_{rec.id}.png",
                             title=f"Vibration against speed: {rec.id}")
        entry: dict[str, Any] = {"against_speed": curve.summary()}
        blades, source = _blades(args, rec)
        peak = rotor = bp = None
        try:
            spec = vibration_spectrum(rec.samples, blades)
        except LogError as exc:
            notes.append(f"{rec.id}: no vibration spectrum ({exc})")
        else:
            plot_vibration_spectrum(spec, out / f"vibration_psd_{rec.id}.png")
            peak, rotor, bp = spec.peak_hz, spec.rotor_hz, spec.blade_pass_hz
            entry["spectrum"] = {**spec.summary(), "blades_from": source}
            if source == "assumed":
                notes.append(f"{rec.id}: blade-pass frequency for 2 blades (assumed; "
                             "--blades N)")
        i = int(curve.level_m_s2.argmax())
        rows.append((rec.id, curve.source, curve.rpm[0], curve.level_m_s2[0], curve.rpm[-1],
                     curve.level_m_s2[-1], curve.rpm[i], curve.level_m_s2[i], peak, rotor, bp))
        summary.setdefault("vibration", {})[rec.id] = entry
    if not rows and args.blades is not None:
        notes.append("--blades: no run has a vibration column (acc_*_m_s2, vibration_m_s2)")
    if rows:
        t = Table("Vibration against speed",
                  ("run", "source", "rpm low", "vib. low [m/s2]", "rpm high",
                   "vib. high [m/s2]", "rpm at max", "vib. max [m/s2]", "PSD peak [Hz]",
                   "rotor [Hz]", "blade pass [Hz]"), tuple(rows),
                  note="vibration: the logged level (median per speed bin) or the rms of the "
                       "acceleration about its mean; PSD: Welch over the top steady hold")
        console.print(t.to_rich())
        write_csv(t, out / "vibration.csv")


def handler(args: argparse.Namespace) -> int:
    from analysis.run_record import read_run

    args.runs = [run_folder_arg(args, r) for r in args.runs]
    out = args.out or Path(f"report-{read_run(args.runs[0]).id}")
    if out.exists() and not (out.is_dir() and (out / "report.json").is_file()):
        # only an earlier report (it holds report.json) is replaced: never a run root,
        # a run folder or a user's file
        raise RigError(f"--out {out}: exists and is not a report folder (no report.json in "
                       "it); refusing to replace it, choose a new folder")
    refuse_foreign(out, "--out", "report", REPORT_NAMES)
    check_writable(out, "--out", folder=True, beside=True)
    tmp = out.with_name(f".{out.name}.tmp")
    if tmp.exists():
        shutil.rmtree(tmp)
    tmp.mkdir(parents=True)
    console = Console(width=shutil.get_terminal_size((160, 24)).columns)
    try:
        summary = build(args, tmp, console)
        with open(tmp / "report.json", "w", encoding="utf-8") as fh:
            json.dump(summary, fh, indent=2, default=float)
        write_manifest(tmp)
        refuse_foreign(out, "--out", "report", REPORT_NAMES)  # added to while we worked
        old = out.with_name(f".{out.name}.old")
        shutil.rmtree(old, ignore_errors=True)  # left by an interrupted earlier report
        if out.exists():
            os.replace(out, old)
        os.replace(tmp, out)
        shutil.rmtree(old, ignore_errors=True)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    files = sorted(p.name for p in out.iterdir())
    console.print(f"{out}: {', '.join(files)}")
    return 0

