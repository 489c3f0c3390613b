"""``rotorbench fit RUN``: latency, time constants and gain of a step run (Table C.1)."""

from __future__ import annotations

import argparse
import json
import math
import shutil
from pathlib import Path
from typing import Any

from rich.console import Console

from bench.cli_args.budget_text import budget_lines, with_expanded
from bench.cli_args.store_args import add_store_args, run_folder_arg
from bench.errors import RigError


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "fit", help="fit delay + first-order lag to the step edges of a run (Table C.1)",
        description="Finds the command edges of a run (e.g. `rotorbench step`), fits a "
                    "first-order-plus-delay model to every edge and to the mean of the "
                    "repeats, separately for rising and falling edges (Paper C Table C.1).")
    p.add_argument("run", type=Path, help="run folder, or a run id of --store")
    p.add_argument("--json", action="store_true", help="print the results as JSON")
    p.add_argument("--signal", choices=("auto", "thrust", "rpm"), default="auto",
                   help="response to fit: load-cell thrust or rotor speed (auto: thrust if "
                        "logged and sampled fast enough, else rpm; says which was used)")
    p.add_argument("--command", default=None, metavar="COL",
                   help="command column of the steps (default: throttle_us, "
                        "thrust_setpoint_n, then an ESC log's duty_pct)")
    p.add_argument("--window", type=float, default=0.5,
                   help="seconds after each edge to fit (default 0.5, shortened to the hold)")
    p.add_argument("--second-order", action="store_true",
                   help="also fit delay + two real poles (the form of C.1)")
    p.add_argument("--budget", action="store_true",
                   help="print each constant's uncertainty budget term by term (GUM)")
    add_store_args(p)
    p.set_defaults(func=handler)


def handler(args: argparse.Namespace) -> int:
    from analysis.metrology.constant_budgets import step_budgets
    from analysis.report import OUTPUT_DELAY, output_delay_line, table_c1
    from analysis.run_record import read_run
    from analysis.step_response import fit_run

    if not (math.isfinite(args.window) and args.window > 0):
        raise RigError(f"--window: expected seconds > 0 after each edge, got {args.window:g}")
    record = read_run(run_folder_arg(args, args.run))
    fit = fit_run(record, signal=args.signal, command=args.command, window_s=args.window,
                  second_order=args.second_order)
    summary = fit.summary()
    # each constant's standard uncertainty and budget (GUM), U at k = 2
    summary["uncertainty"] = {k: b.as_dict() for k, b in step_budgets(fit).items()}
    summary["run"] = str(record.path)
    summary["esc_mode"] = record.components.get("esc_mode")
    if record.meta.get(OUTPUT_DELAY) is not None:  # an ESC that is a firmware: it was timed
        summary[OUTPUT_DELAY] = record.meta[OUTPUT_DELAY]
    if args.json:
        print(json.dumps(summary, indent=2, allow_nan=False))
        return 0
    label = str(record.components.get("esc_mode") or record.id)
    console = Console(width=shutil.get_terminal_size((160, 24)).columns)
    console.print(table_c1([(label, fit)]).to_rich())
    delay = output_delay_line(record.meta)
    unc = summary["uncertainty"]
    lines = [*text_summary(summary), *([delay] if delay else []),
             "; ".join(with_expanded(k, b) for k, b in unc.items())]
    if args.budget:
        lines += [line for k, b in unc.items() for line in budget_lines(k, b)]
    for line in lines:
        console.print(line, highlight=False, markup=False)
    return 0


def _num(x: float | None, unit: str = "", fmt: str = ".4g") -> str:
    return "n/a" if x is None else f"{x:{fmt}}{unit}"


def text_summary(s: dict[str, Any]) -> list[str]:
    """The lines under the table; every number may be missing (``n/a`` and why)."""
    edges = s.get("edges", [])
    lines = [f"signal {s['signal']}, command {s['command']}"]
    lines += [f"note: {n}" for n in s.get("notes", [])]
    for name, long in (("up", "rising"), ("down", "falling")):
        src = s.get(f"summary_{name}")
        if src is None:
            why = next((e.get("why") for e in edges if e["direction"] == name and e.get("why")),
                       f"no {long} edge in the run")
            lines.append(f"{name}: n/a ({why})")
            continue
        lines.append(f"{name}: latency {_num(s[f'latency_{name}_ms'], ' ms', '.3g')}, tau "
                     f"{_num(s[f'tau_{name}_ms'], ' ms', '.3g')} (+- "
                     f"{_num(s[f'tau_{name}_std_ms'], ' ms', '.2g')}), t63 "
                     f"{_num(s[f'rise_time_63_{name}_ms'], ' ms', '.3g')}, gain "
                     f"{_num(s[f'gain_{name}'])} {s['gain_unit']}; {src['from']}; edges "
                     f"{_ranges(src['edges'])}")
    rms = s.get("rise_fall_rms")
    lines.append(f"gain {_num(s.get('gain'))} {s['gain_unit']}; rise/fall rms "
                 + (_num(rms) if rms is not None else
                    "n/a (needs the same level pair fitted in both directions)"))
    skipped = [e for e in edges if not e.get("fitted")]
    counts = {}
    for e in skipped:
        counts[e.get("why", "")] = counts.get(e.get("why", ""), 0) + 1
    lines.append(f"{s['repeats_up']} rising and {s['repeats_down']} falling edges fitted of "
                 f"{len(edges)}" + "".join(f"; {n} not: {w}" for w, n in counts.items()))
    return lines


def _ranges(idx: list[int]) -> str:
    """[1, 2, 3, 7] -> '1-3, 7' (edge numbers as in --json 'edges')."""
    out: list[str] = []
    for i in idx:
        if out and out[-1].split("-")[-1] == str(i - 1):
            out[-1] = f"{out[-1].split('-')[0]}-{i}"
        else:
            out.append(str(i))
    return ", ".join(out) or "none"
