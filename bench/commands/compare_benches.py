"""``rotorbench compare-benches``: do the lab's benches measure the same motor the same way?

Lists every bench's stored constants of one motor and propeller with their expanded
uncertainties and the normalised error E_n of every pair (``bench.store.bench_comparison``,
``analysis.metrology.interlab``); a pair with |E_n| > 1 is flagged and the command exits 1.
"""

from __future__ import annotations

import argparse
import json
import shutil
from pathlib import Path

from rich.console import Console
from rich.table import Table

from bench.cli_args.budget_text import DISPLAY, display, value_and_u
from bench.cli_args.store_args import add_store_args, store_from_args
from bench.paths.outputs import check_figure_path
from bench.store.bench_comparison import BenchComparison, compare_benches


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "compare-benches", help="compare the constants every bench measured for one motor "
                                "and propeller (E_n, ISO/IEC 17043)",
        description="Reads the constants every bench of the store fitted for one motor and "
                    "propeller (each bench's newest fit of each kind) and prints each "
                    "constant's value and expanded uncertainty U (k = 2) by bench and the "
                    "normalised error E_n = (x1 - x2) / sqrt(U1^2 + U2^2) of every pair; "
                    "|E_n| > 1 is flagged. Exit 1 when a pair is flagged. "
                    "docs/calibration.md.")
    p.add_argument("--motor", required=True, help="the motor's id, as the runs name it")
    p.add_argument("--propeller", required=True, help="the propeller's id")
    p.add_argument("--esc", default=None, help="the ESC's id (needed when benches used several)")
    p.add_argument("--esc-mode", default=None, help="the ESC mode (idem)")
    p.add_argument("--battery", default=None, help="the battery or supply (idem)")
    p.add_argument("--json", action="store_true", help="print the comparison as JSON")
    p.add_argument("--plot", type=Path, default=None, metavar="FILE",
                   help="write the figure (values +- U by bench, a panel per constant)")
    add_store_args(p)
    p.set_defaults(func=handler)


def handler(args: argparse.Namespace) -> int:
    if args.plot is not None:
        check_figure_path(args.plot)
    store = store_from_args(args)
    result = compare_benches(store, args.motor, args.propeller, esc=args.esc,
                             esc_mode=args.esc_mode, battery=args.battery)
    if args.plot is not None:
        from analysis.metrology.interlab_figure import plot_comparison

        plot_comparison(result.constants, args.plot,
                        title=f"{args.motor} / {args.propeller}: value +- U (k = 2) by bench; "
                              "red: |E_n| > 1 against every other bench, orange: some")
    if args.json:
        print(json.dumps(result.as_dict(), indent=2, allow_nan=False))
    else:
        _print(result)
        if args.plot is not None:
            print(f"figure: {args.plot}")
    return 1 if result.flagged else 0


def _label(name: str) -> str:
    return display(name)[0]


def _cell(name: str, value: float, big_u: float | None) -> str:
    """``29.71 ± 0.27`` in the constant's display unit (``DISPLAY``), as ``fit`` and
    ``constants`` print it (``value_and_u``); ``?`` for a U not known."""
    _, f, _, fmt = display(name)
    if big_u is None:
        return f"{format(value * f, fmt)} ± ?"
    return " ± ".join(value_and_u(value * f, big_u * f))


def _print(result: BenchComparison) -> None:
    console = Console(width=shutil.get_terminal_size((160, 24)).columns)
    a = result.actuator
    benches = [b.bench for b in result.benches]
    values = Table(title=f"{a['motor']} / {a['propeller']} / {a['esc']} ({a['esc_mode']}) / "
                         f"{a['battery']} in {result.store}: value ± U (k = 2)")
    values.add_column("constant")
    for b in benches:
        values.add_column(b, overflow="fold")
    for c in result.constants:
        by = {p.bench: p for p in c.participants}
        unit = DISPLAY.get(c.name, (c.name, 1.0, c.unit))[2]
        values.add_row(f"{_label(c.name)} ({unit})", *(
            "" if b not in by else _cell(c.name, by[b].value, by[b].expanded)
            for b in benches))
    console.print(values)
    pairs = Table(title="normalised error E_n = (x1 - x2) / sqrt(U1² + U2²); |E_n| > 1 "
                        "flagged (ISO/IEC 17043)")
    for col in ("constant", "benches", "E_n", ""):
        pairs.add_column(col)
    for c in result.constants:
        for p in c.pairs:
            en = "no U" if p.e_n is None else f"{p.e_n:+.2f}"
            pairs.add_row(_label(c.name), f"{p.bench_a} vs {p.bench_b}", en,
                          "FLAGGED" if p.flagged else "")
    console.print(pairs)
    for b in result.benches:
        cal = f"; calibration {', '.join(b.calibrations)}" if b.calibrations else ""
        console.print(f"{b.bench}: " + ", ".join(f"{k} {r}" for k, r in sorted(b.runs.items()))
                      + cal, highlight=False, soft_wrap=True)
    for note in result.notes:
        console.print(f"note: {note}", highlight=False, soft_wrap=True)
    flagged = result.flagged
    console.print(f"{len(flagged)} of {sum(len(c.pairs) for c in result.constants)} pairs "
                  "flagged" + (": " + "; ".join(f"{_label(c)} {x} vs {y} E_n {e:+.2f}"
                                                for c, x, y, e in flagged) if flagged else ""),
                  highlight=False, soft_wrap=True)
