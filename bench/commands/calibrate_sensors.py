"""``rotorbench calibrate-sensors``: calibrate the stand's load or torque cell with known
weights, step by step (prompted) or with an automatic fixture, and record the calibration."""

from __future__ import annotations

import argparse
import sys
from dataclasses import replace
from pathlib import Path

from bench.cli_args.option_values import seed_arg
from bench.cli_args.store_args import DEFAULT_OUT, add_store_args, publish_runs, recording_store
from bench.errors import RigError


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "calibrate-sensors", help="calibrate the load or torque cell with known weights",
        description="Tare, then known weights in ascending and descending order, each held "
                    "and recorded; fits scale and offset by weighted least squares and "
                    "reports non-linearity, hysteresis, creep, repeatability and zero "
                    "return, with the scale's uncertainty budget (GUM, U at k = 2). The "
                    "calibration is recorded as a run of kind 'calibration' (never "
                    "overwritten); later runs on the rig apply the newest valid one. The "
                    "ESC is never armed. Exit 1 when the calibration fails the rig file's "
                    "acceptance limits ([calibration]). docs/calibration.md.")
    p.add_argument("--rig", type=Path, default=None,
                   help="rig file (TOML); default: the simulated rig bench/data/rigs/sim.toml")
    p.add_argument("--out", type=Path, default=DEFAULT_OUT,
                   help="output root for run folders and runs.sqlite (default: ./runs)")
    p.add_argument("--cell", choices=("thrust", "torque"), default=None,
                   help="which cell (default thrust)")
    p.add_argument("--masses-g", default=None, metavar="G,G,...",
                   help="the weights in grams, ascending from 0 (default 0,100,200,500,1000)")
    p.add_argument("--weight-class", default=None, metavar="E2|F1|F2|M1|M2",
                   help="the weights' OIML R 111 class (default F1)")
    p.add_argument("--mass-u-g", type=float, default=None,
                   help="the weights' standard uncertainty in grams, instead of a class")
    p.add_argument("--arm-m", type=float, default=None,
                   help="torque: the arm's length from the motor axis to the weight (m)")
    p.add_argument("--arm-u-m", type=float, default=None,
                   help="torque: the arm length's standard uncertainty (m)")
    p.add_argument("--hold-s", type=float, default=None, help="seconds each weight is held (3)")
    p.add_argument("--settle-s", type=float, default=None,
                   help="seconds before each hold, not recorded into the fit (1)")
    p.add_argument("--series", type=int, default=None, help="up/down series (1)")
    p.add_argument("--plan", type=Path, default=None,
                   help="a plan file (TOML [calibration]: cell, masses_g, weight_class, "
                        "mass_u_g, arm_m, arm_u_m, settle_s, hold_s, series)")
    p.add_argument("--yes", action="store_true",
                   help="no prompts: the rig's automatic fixture puts the weights on (a "
                        "simulated rig has one)")
    p.add_argument("--operator", default=None, help="who calibrates (default: the login)")
    p.add_argument("--seed", type=seed_arg, default=None, help="seed of the simulated rig")
    p.add_argument("--json", action="store_true", help="print the record as JSON")
    add_store_args(p, records=True)
    p.set_defaults(func=handler)


def _plan(args: argparse.Namespace):
    from bench.plans.weight_series import CalibrationPlan, parse_masses_g, plan_from_file

    base = plan_from_file(args.plan) if args.plan is not None else CalibrationPlan()
    given = {"cell": args.cell, "weight_class": args.weight_class, "arm_m": args.arm_m,
             "arm_u_m": args.arm_u_m, "hold_s": args.hold_s, "settle_s": args.settle_s,
             "series": args.series}
    kw = {k: v for k, v in given.items() if v is not None}
    if args.masses_g is not None:
        kw["masses_kg"] = parse_masses_g(args.masses_g)
    if args.mass_u_g is not None:
        kw["mass_u_kg"] = args.mass_u_g * 1e-3
    return replace(base, **kw)


def handler(args: argparse.Namespace) -> int:
    from bench.cli_args.run_args import load_rig_from_args
    from bench.engine.recorder import operator
    from bench.jobs.sensor_calibration import run_sensor_calibration, site_references
    from bench.jobs.weight_loaders import OperatorLoader, sim_fixture
    from bench.paths.outputs import check_writable
    from drivers.factory import open_rig

    plan = _plan(args)
    args.esc_mode = None
    rig_cfg = load_rig_from_args(args)
    store = recording_store(args, warn=lambda line: print(line, file=sys.stderr))
    check_writable(args.out, "--out", folder=True)
    site = rig_cfg.calibration
    if site is None:
        raise RigError(f"{rig_cfg.path}: an IMU-bench rig; calibrate-sensors calibrates a "
                       "propulsion stand's load or torque cell")
    gravity, acceptance = site_references(site)
    meta = {"operator": args.operator or operator(), "command_line": sys.argv[1:]}
    with open_rig(rig_cfg, seed=args.seed) as rig:
        if args.yes:
            loader = sim_fixture(rig, plan.cell)
            if loader is None:
                raise RigError(f"--yes: {rig_cfg.path} has no automatic fixture the bench "
                               "can drive; calibrate step by step (without --yes)")
        else:
            loader = OperatorLoader(_ask, plan.cell, plan.arm_m)
        print(f"calibrating the {plan.cell} cell of {rig_cfg.name}: "
              f"{len(plan.steps())} steps, g = {gravity.g:.5f} m/s^2 ({gravity.source})")
        outcome = run_sensor_calibration(
            rig_cfg, rig, plan, loader, gravity, args.out, acceptance=acceptance, meta=meta,
            on_step=lambda i, n, what: print(f"  [{i}/{n}] {what}"))
    publish_runs(store, outcome.run_dir, tell=print)
    _report(outcome, args.json)
    return 0 if outcome.record["acceptance"]["passed"] else 1


def _ask(prompt: str) -> None:
    try:
        input(prompt)
    except EOFError:
        raise RigError("calibrate-sensors: no operator at the prompt (standard input "
                       "closed); use --yes with an automatic fixture") from None


def _report(outcome, as_json: bool) -> None:
    import json

    rec = outcome.record
    if as_json:
        print(json.dumps(rec, indent=2))
        return
    fit = outcome.fit
    budget = fit.scale_budget
    ch = fit.characteristics()
    unit = "N m" if rec["applies"]["channel"] == "torque_nm" else "N"
    print(f"{outcome.run_dir}: calibration {rec['id']} (figure calibration.png)")
    print(f"  gain {fit.scale:.6g} +- {budget.expanded * abs(fit.scale):.2g} (k = 2), "
          f"offset {fit.offset:.5g} {unit}: {rec['applies']['rule']}")
    print("  " + ", ".join(f"{k.replace('_', ' ')} {v * 100:.3g} %" for k, v in ch.items())
          + " of full scale")
    for t in budget.terms:
        print(f"    u {t.u * 100:9.4f} %  {t.name} (type {t.kind})")
    acc = rec["acceptance"]
    print(f"  accepted; valid until {rec['valid_until_utc']}" if acc["passed"] else
          "  NOT accepted: " + "; ".join(acc["failed"]))
