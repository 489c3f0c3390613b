"""``rotorbench fit RUN``: latency, time constants and gain of a step run (Table C.1)."""

from __future__ import annotations

import argparse
import json
import math
import shutil
from pathlib import Path

from rich.console import Console

from bench.errors import RigError


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "fit", help="fit delay + first-order lag to the step edges of a run (Table C.1)",
        description="Finds the command edges of a run (e.g. `rotorbench step`), fits a "
                    "first-order-plus-delay model to every edge and to the mean of the "
                    "repeats, separately for rising and falling edges (Paper C Table C.1).")
    p.add_argument("run", type=Path, help="run folder")
    p.add_argument("--json", action="store_true", help="print the results as JSON")
    p.add_argument("--signal", choices=("auto", "thrust", "rpm"), default="auto",
                   help="response to fit: load-cell thrust or rotor speed (auto: thrust if "
                        "logged)")
    p.add_argument("--window", type=float, default=0.5,
                   help="seconds after each edge to fit (default 0.5, shortened to the hold)")
    p.add_argument("--second-order", action="store_true",
                   help="also fit delay + two real poles (the form of C.1)")
    p.set_defaults(func=handler)


def handler(args: argparse.Namespace) -> int:
    from analysis.report import table_c1
    from analysis.run_record import read_run
    from analysis.step_response import fit_run

    if not (math.isfinite(args.window) and args.window > 0):
        raise RigError(f"--window: expected seconds > 0 after each edge, got {args.window:g}")
    record = read_run(args.run)
    fit = fit_run(record, signal=args.signal, window_s=args.window,
                  second_order=args.second_order)
    summary = fit.summary()
    summary["run"] = str(record.path)
    summary["esc_mode"] = record.components.get("esc_mode")
    if args.json:
        print(json.dumps(summary, indent=2, allow_nan=False))
        return 0
    label = str(record.components.get("esc_mode") or record.id)
    console = Console(width=shutil.get_terminal_size((160, 24)).columns)
    console.print(table_c1([(label, fit)]).to_rich())
    console.print(f"gain {summary['gain']:.4g} {fit.gain_unit} (up {summary['gain_up']:.4g}, "
                  f"down {summary['gain_down']:.4g}); {summary['repeats_up']} rising and "
                  f"{summary['repeats_down']} falling edges fitted of {len(fit.edges)}; "
                  f"signal {fit.signal}")
    for name in ("up", "down"):
        so = summary.get(f"second_order_{name}")
        if so:
            console.print(f"second order ({name}): delay {so['latency_ms']:.2f} ms, tau1 "
                          f"{so['tau1_ms']:.2f} ms, tau2 {so['tau2_ms']:.2f} ms")
    return 0
