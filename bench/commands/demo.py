"""``rotorbench demo``: the whole loop on the simulated rig, from runs to designs.

For every motor and propeller of the ``thesis-e`` catalog (Paper E, Tables E.5-E.7) the
default sim rig gets that actuator's parameters (K_V, R_a, inertia, diameter, C_t, C_p,
the battery's in-flight voltage), runs a slow sweep (static curves and the thrust map),
Paper C's Step 1 and Step 2 around its own hover thrust; one combination also runs in the
three ESC modes. Every run is fitted and its constants stored; then Paper E's three test
cases are optimized with the datasheet model and with the measured constants, and the
tables (Table C.1, E.8-E.10-like selections, E.11, E.13, E.14) and figures are written.
The designs come from the real optimizer (``optimizer.solve.selection.optimize``, exact MILP,
the CLI's tie rules) with ``optimize``'s hover margin (``--min-thrust-to-weight``, default
1.2; ``--thesis-rules`` for the thesis' model, where some exact optima cannot hover).
The output folder is built beside its final name and renamed into place at the end; an
existing ``--out`` is only replaced when it holds the marker file a previous demo wrote
(anything else, e.g. ``--out .``, is refused with exit status 2).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import shutil
import time
from pathlib import Path
from typing import Any

import numpy as np
from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

from analysis.atomic_files import temp_beside
from bench.cli_args.option_values import seed_arg
from bench.cli_args.sizing_args import add_hover_args, hover_margin_from_args
from bench.errors import RigError
from bench.paths.outputs import check_writable
from bench.paths.owned_folder import refuse_foreign, write_manifest
from optimizer.cases.paper_e_cases import PAPER_E_CASES

G0 = 9.80665
ACTUATORS = (4, 6, 8)
#: Written into every demo output; only a folder holding it may be replaced.
MARKER = ".rotorbench-demo"
MARKER_TEXT = "rotorbench demo output; `rotorbench demo --out` may replace this folder\n"
#: What a demo folder held before its manifest (:mod:`bench.paths.owned_folder`).
DEMO_NAMES = (MARKER, "demo.json", "runs", "figures", "tables")
#: Metric keys whose source the designs table reports.
SOURCE_KEYS = ("time_constant_ms", "current_a", "power_w", "flight_time_min")
MODES = ("complementary", "diode", "stock")
#: Step 1 repeats a demo may ask per combination: 100 already take minutes of rig
#: time per combination; a million ran for days without a word.
MAX_REPEATS = 100


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "demo", help="run the whole loop on the simulated rig (runs, fits, constants, designs)",
        description="Sweeps and Step 1 / Step 2 runs for every motor x propeller of the "
                    "thesis-e catalog on the simulated rig, the three ESC modes on one "
                    "combination, fits, a constants store, and Paper E's three test cases "
                    "optimized with and without the measured constants.")
    p.add_argument("--out", type=Path, default=Path("demo-out"),
                   help="output folder (default ./demo-out); an existing one is replaced only "
                        f"if a previous demo wrote it (it holds {MARKER}) and it holds "
                        "nothing else, else refused")
    p.add_argument("--repeats", type=int, default=3, help="Step 1 repeats per combination")
    p.add_argument("--seed", type=seed_arg, default=1, help="seed of the simulated rig")
    p.add_argument("--combos", type=int, default=None,
                   help="only the first N motor x propeller combinations (quick look)")
    add_hover_args(p)
    p.set_defaults(func=handler)


def combo_rig(base: Any, catalog: Any, i: int, j: int, mode: str, seed: int) -> Any:
    """The default sim rig with propeller ``i`` on motor ``j`` of the catalog."""
    from bench.rig.rig import Limits
    from optimizer.model.design_model import (
        battery_voltage_v,
        motor_inertia_kgm2,
        propeller_inertia_kgm2,
    )
    from optimizer.model.physics import torque_constant

    prop = catalog.propellers.iloc[i]
    mot = catalog.motors.iloc[j]
    kt = float(torque_constant(float(mot["kv_rad_s_per_v"])))  # (2.37) in SI
    plant = {
        "kt_nm_a": kt, "ke_v_s_rad": kt, "r_ohm": float(mot["resistance_ohm"]),
        "j_kg_m2": float(propeller_inertia_kgm2(catalog)[i] + motor_inertia_kgm2(catalog)[j]),
        "diameter_m": float(prop["diameter_m"]), "ct": float(prop["ct"]),
        "cp": float(prop["cp"]), "supply_v": float(np.max(battery_voltage_v(catalog))),
    }
    comp = dataclasses.replace(base.components, catalog="thesis-e",
                               motor=catalog.motor_ids[j], propeller=catalog.propeller_ids[i],
                               esc="sim-f30a", esc_mode=mode, battery="3s-in-flight-12v")
    limits = Limits(thrust_n=80.0, current_a=80.0, rpm=20000.0, voltage_min_v=6.0,
                    voltage_max_v=20.0, temperature_c=80.0, source="demo rig")
    sim = dataclasses.replace(base.sim, plant=plant, esc_mode=mode, seed=seed)
    return dataclasses.replace(base, components=comp, limits=limits, sim=sim, thrust_map=None,
                               name=f"sim-{catalog.propeller_ids[i]}-{catalog.motor_ids[j]}")


def _optimize_cases(catalog: Any, measured: Any, progress: Any, task: Any) -> list[Any]:
    """Paper E's test cases by the real optimizer (exact MILP, the CLI's tie rules), with
    the datasheet model and with the measured constants where the store has them
    (``catalog`` carries the run's hover margin)."""
    from optimizer.solve.objectives import single
    from optimizer.solve.selection import Requirements
    from optimizer.solve.selection_options import solve

    cases = []
    for case, title, objective, payload in PAPER_E_CASES:
        req = Requirements(payload_kg=payload)
        pair = {}
        for label, over in (("model", None), ("measured", measured)):
            progress.update(task, description=f"optimize case {case} ({label})")
            pair[label] = solve(catalog, single(objective), ACTUATORS, req, "milp", over)
            progress.advance(task)
        cases.append((case, title, pair))
    return cases


def check_out(out: Path) -> Path:
    """The absolute output folder, refused (exit 2) unless it is new or a previous demo's."""
    out = Path(os.path.abspath(out))
    if out.parent == out:
        raise RigError(f"--out {out}: refusing the file-system root")
    cwd = Path(os.path.abspath(os.getcwd()))
    if not out.exists() and not out.is_symlink():
        return out
    if out.is_symlink() or not out.is_dir():
        raise RigError(f"--out {out}: exists and is not a folder; choose a new folder")
    if not (out / MARKER).is_file():
        raise RigError(f"--out {out}: exists and was not written by `rotorbench demo` (no "
                       f"{MARKER} in it); refusing to replace it, choose a new folder")
    if cwd == out or out in cwd.parents:
        raise RigError(f"--out {out}: is the current folder or contains it; run from elsewhere")
    refuse_foreign(out, "--out", "demo", DEMO_NAMES)
    return out


def handler(args: argparse.Namespace) -> int:
    from analysis.figures import plot_static, plot_steps, plot_validation
    from analysis.flight_time import flight_time_min, hover_current_a
    from analysis.report import Table, table_c1, table_e11, table_e13, table_e14, write_csv
    from analysis.run_record import read_run
    from analysis.static_curves import fit_static_run
    from analysis.step_response import fit_run
    from analysis.validation import validate_run
    from bench.plan_runner.runner import RunOptions
    from bench.plan_runner.session import run_sequence
    from bench.plans.stand_sequences import step1, step2, sweep
    from bench.plans.thrust_map import fit_sweep_run
    from bench.rig.rig import default_rig_path, load_rig
    from bench.store.catalogs import shipped_catalog
    from bench.store.constants_fit import fit_for_store
    from bench.store.constants_store import ConstantsStore
    from bench.store.measured_constants import MeasuredSet, load_measured
    from drivers.factory import open_rig

    wall0 = time.monotonic()
    console = Console(width=shutil.get_terminal_size((160, 24)).columns)
    if args.combos is not None and args.combos < 1:
        raise RigError(f"--combos: expected a count >= 1, got {args.combos}")
    margin = hover_margin_from_args(args)
    if not 1 <= args.repeats <= MAX_REPEATS:
        raise RigError(f"--repeats: expected a count from 1 to {MAX_REPEATS} (the demo runs "
                       f"every combination; `rotorbench step --repeats` for long runs), "
                       f"got {args.repeats}")
    out = check_writable(check_out(args.out), "--out", folder=True, beside=True)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = temp_beside(out, ".tmp", folder=True)  # the umask's mode, not mkdtemp's 0700
    runs_root, figs, tabs = tmp / "runs", tmp / "figures", tmp / "tables"
    for d in (runs_root, figs, tabs):
        d.mkdir(parents=True)
    catalog = shipped_catalog("thesis-e")
    base = load_rig(default_rig_path())
    # simulated rig only: the plant advances per tick, not with the wall clock, so a host
    # busy with other jobs (2 cores) must not end a run as a "stalled" command loop
    opts = RunOptions(tick_s=0.02, watchdog_timeout_s=2.0)
    combos = [(i, j) for i in range(len(catalog.propeller_ids))
              for j in range(len(catalog.motor_ids))][: args.combos]
    mode_combo = (0, 0)  # Test Case III's actuator (P1, M1) also runs the other modes
    n_tasks = 3 * len(combos) + 3 * (len(MODES) - 1) + 2 * len(PAPER_E_CASES)
    progress = Progress(TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(),
                        TimeElapsedColumn(), console=Console(stderr=True))
    task = progress.add_task("demo", total=n_tasks)
    store = ConstantsStore(runs_root)
    fits: dict[tuple[int, int, str], Any] = {}
    statics: dict[tuple[int, int], Any] = {}
    step2_runs: dict[tuple[int, int, str], Path] = {}

    def run(rig: Any, seq: Any, label: str) -> Path:
        progress.update(task, description=label)
        outcome = run_sequence(rig, seq, runs_root, open_rig, options=opts)
        if outcome.result.status != "success":
            raise RuntimeError(f"{label}: {outcome.result.status}: {outcome.result.reason}")
        progress.advance(task)
        return outcome.run_dir

    try:
        with progress:
            for i, j in combos:
                name = f"{catalog.propeller_ids[i]}-{catalog.motor_ids[j]}"
                modes = MODES if (i, j) == mode_combo else MODES[:1]
                for mode in modes:
                    # each ESC mode gets its own sweep: the static map depends on the scheme
                    rig = combo_rig(base, catalog, i, j, mode, args.seed)
                    sw = run(rig, sweep(1050.0, 2000.0, 8.0), f"{name} {mode} sweep")
                    tm = fit_sweep_run(sw).thrust_map
                    if mode == MODES[0]:
                        statics[(i, j)] = fit_static_run(read_run(sw))
                    key, kind, rid, data = fit_for_store(sw)
                    store.put(key, kind, rid, str(sw), data)
                    hover = 0.35 * float(tm.thrust_n[-1])
                    band = (0.7 * hover, 1.3 * hover)  # hover +-30 %, as Paper C's Step 1
                    r = rig.with_thrust_map(tm.command_us.tolist(), tm.thrust_n.tolist())
                    s1 = run(r, step1(repeats=args.repeats, hold_s=1.0, settle_s=1.0,
                                      band_n=band), f"{name} {mode} step1")
                    fits[(i, j, mode)] = fit_run(read_run(s1), window_s=2.0)
                    key, kind, rid, data = fit_for_store(s1)
                    store.put(key, kind, rid, str(s1), data)
                    step2_runs[(i, j, mode)] = run(
                        r, step2(repeats=2, hold_s=1.0, settle_s=1.0, band_n=band),
                        f"{name} {mode} step2")
            measured = MeasuredSet(runs_root, MODES[0], load_measured(runs_root, "thesis-e"))
            cases = _optimize_cases(margin.apply(catalog), measured, progress, task)
        summary = _tables_and_figures(
            console, catalog, fits, statics, step2_runs, measured, cases, mode_combo, figs, tabs,
            dict(plot_static=plot_static, plot_steps=plot_steps, plot_validation=plot_validation,
                 table_c1=table_c1, table_e11=table_e11, table_e13=table_e13,
                 table_e14=table_e14, write_csv=write_csv, Table=Table, read_run=read_run,
                 validate_run=validate_run, hover_current_a=hover_current_a,
                 flight_time_min=flight_time_min))
        summary["hover_margin"] = margin.to_dict(margin.apply(catalog))
        console.print(margin.describe(margin.apply(catalog)))
        summary["wall_time_s"] = time.monotonic() - wall0
        with open(tmp / "demo.json", "w", encoding="utf-8") as fh:
            json.dump(summary, fh, indent=2, default=str)
        (tmp / MARKER).write_text(MARKER_TEXT, encoding="utf-8")
        write_manifest(tmp)
        old = None
        if out.exists():
            check_out(out)  # still a previous demo's output, with nothing of the user's
            old = temp_beside(out, ".old", folder=True)
            os.replace(out, old)  # onto the empty placeholder
        os.replace(tmp, out)
        if old is not None:
            shutil.rmtree(old, ignore_errors=True)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    console.print(f"{out}: runs, constants.sqlite, figures/ and tables/ written in "
                  f"{time.monotonic() - wall0:.1f} s")
    return 0


def _measured_vs_model(catalog: Any, measured: Any) -> Any:
    """Measured against datasheet-model constants of every measured actuator, at 35 % of
    its measured top thrust (the centre of its Step 1 band). The sim's copper and supply
    losses show up here; the demo prints this rather than hiding the gap. The model's
    numbers come from the optimizer's design model (``actuator_at_thrust``: E.20, E.35,
    E.67 and the full-throttle thrust), the same code that sizes the designs."""
    from analysis.report import Table
    from optimizer.model.design_model import actuator_at_thrust, battery_voltage_v

    volt = float(np.max(battery_voltage_v(catalog)))
    rows = []
    for item in measured.overrides:
        if item.esc_mode != measured.esc_mode or item.top_thrust_n is None:
            continue
        i = catalog.propeller_ids.index(item.propeller_id)
        j = catalog.motor_ids.index(item.motor_id)
        t_ref = 0.35 * item.top_thrust_n
        model = actuator_at_thrust(catalog, i, j, t_ref, volt)
        tau_model = model.hover.time_constant_s  # (E.35) at the (E.20) speed
        cur_model = model.hover.current_a  # (E.67)
        top_model = model.top_thrust_n
        cur, inside = item.current_at(np.array([t_ref]), np.array([volt]))
        tau = item.time_constant_s
        rows.append((f"{item.propeller_id}-{item.motor_id}", t_ref,
                     None if tau is None else tau * 1e3, float(tau_model) * 1e3,
                     None if tau is None else 100.0 * (tau / float(tau_model) - 1.0),
                     float(cur[0]) if inside[0] else None, float(cur_model),
                     100.0 * (float(cur[0]) / float(cur_model) - 1.0) if inside[0] else None,
                     item.top_thrust_n, float(top_model)))
    return Table(f"Measured vs datasheet model ({measured.esc_mode} ESC, {volt:g} V)",
                 ("actuator", "at thrust [N]", "tau meas [ms]", "tau model [ms]", "tau diff %",
                  "I meas [A]", "I model [A]", "I diff %", "top thrust meas [N]",
                  "top thrust model [N]"), tuple(rows),
                 note="the sim's motors have copper and supply losses the model (E.67) "
                      "leaves out: measured currents are higher, flight times shorter")


def _tables_and_figures(console, catalog, fits, statics, step2_runs, measured, cases,
                        mode_combo, figs, tabs, f) -> dict[str, Any]:
    summary: dict[str, Any] = {}
    i0, j0 = mode_combo
    name0 = f"{catalog.propeller_ids[i0]}-{catalog.motor_ids[j0]}"
    # Table C.1 and Fig. C.9-C.12, C.16-C.19 on the three-mode combination
    c1 = [(m, fits[(i0, j0, m)]) for m in MODES if (i0, j0, m) in fits]
    t = f["table_c1"](c1)
    t = dataclasses.replace(t, title=f"Table C.1 on {name0}: first order system with delay")
    console.print(t.to_rich())
    f["write_csv"](t, tabs / "table_c1.csv")
    f["plot_steps"](c1, figs / "steps_three_modes.png", title=f"Step 1 on {name0}")
    static0 = statics[(i0, j0)]
    f["plot_static"](static0, figs / f"static_{name0}.png", title=f"Static curves: {name0}")
    for m in MODES:
        if (i0, j0, m) in step2_runs:
            v = f["validate_run"](f["read_run"](step2_runs[(i0, j0, m)]), fits[(i0, j0, m)])
            f["plot_validation"](v, figs / f"validation_{m}.png",
                                 title=f"Step 2, {m}: RMS error first order "
                                       f"{v.rms_first_order_pct:.1f} % of the band")
    # Tables E.8-E.10: the optimizer's designs, datasheet model and measured constants
    from bench.figures.design_tables import show_table

    sel_rows, e11, e13, e14 = [], [], [], []
    for case, title, pair in cases:
        show_table(pair["model"], console.print, title=f"{title}: datasheet model")
        show_table(pair["measured"], console.print,
                    title=f"{title}: measured constants ({measured.esc_mode} ESC) where stored")
        for label in ("model", "measured"):
            for d in pair[label].designs:
                best = " *" if d is pair[label].best else ""
                if not d.feasible:
                    sel_rows.append((f"{case}-{d.actuators}{best}", label, "infeasible", None,
                                     None, d.reason or ""))
                    continue
                src = d.extra.get("sources") or {}
                sel_rows.append((f"{case}-{d.actuators}{best}", label,
                                 f"{d.propeller} {d.motor} {d.battery}",
                                 d.metrics["time_constant_ms"], d.metrics["flight_time_min"],
                                 ", ".join(k for k in SOURCE_KEYS
                                           if str(src.get(k, "")).startswith("measured"))
                                 or "datasheet"))
        for d in pair["model"].designs:
            if not d.feasible:
                continue
            tag = f"{case}-{d.actuators}"
            pi, mj, bk = d.index
            fit = fits.get((pi, mj, MODES[0]))
            if fit is not None:
                e11.append((tag, fit.up.t63.value, fit.down.t63.value))
                e13.append((tag, fit.up.tau.value, fit.down.tau.value,
                            d.metrics["time_constant_ms"] * 1e-3))
            st = statics.get((pi, mj))
            if st is None:
                continue
            hover = d.metrics["total_mass_kg"] * catalog.constants.gravity_m_s2 / d.actuators
            try:
                cur = f["hover_current_a"](st, hover)
                cap = float(catalog.batteries["capacity_ah"].iloc[bk]) * 1e3
                e14.append((tag, f["flight_time_min"](cap, cur, d.actuators),
                            d.metrics["flight_time_min"]))
            except Exception as exc:  # hover thrust beyond the sweep: say so
                e14.append((tag, None, d.metrics["flight_time_min"]))
                summary.setdefault("notes", []).append(f"{tag}: {exc}")
    ts = f["Table"]("Paper E test cases: datasheet model vs measured constants "
                    "(optimizer.solve.selection, milp; * best count)",
                    ("case-N", "constants", "design (P M B)", "tau [ms]", "flight [min]",
                     "measured metrics"), tuple(sel_rows))
    cmp_table = _measured_vs_model(catalog, measured)
    for tab, fname in ((ts, "designs.csv"), (f["table_e11"](e11), "table_e11.csv"),
                       (f["table_e13"](e13), "table_e13.csv"),
                       (f["table_e14"](e14), "table_e14.csv"),
                       (cmp_table, "measured_vs_model.csv")):
        console.print(tab.to_rich())
        f["write_csv"](tab, tabs / fname)
    summary["designs"] = [dict(zip(ts.columns, r, strict=True)) for r in sel_rows]
    summary["cases"] = [{"case": c, "title": t, "constants": label, **pair[label].to_dict()}
                        for c, t, pair in cases for label in ("model", "measured")]
    summary["measured_vs_model"] = [dict(zip(cmp_table.columns, r, strict=True))
                                    for r in cmp_table.rows]
    summary["table_c1"] = {m: {k: v for k, v in fit.summary().items() if k != "edges"}
                           for m, fit in c1}
    for note in summary.get("notes", []):
        console.print(f"note: {note}")
    return summary
