"""``rotorbench evaluate``: what does my build do? One given design, exactly.

Reports the same keys as an ``optimize --json`` design entry for one actuator
count, propeller, motor and battery, plus every limit check. Exit 0 whether or
not the design is feasible (``feasible`` and ``reason`` say), 2 for bad input.
"""

from __future__ import annotations

import argparse
import json
import time
from typing import Any

from bench.commands._measured import add_measured_args, is_measured
from bench.commands.optimize import (
    MEASURED_MARK,
    ROWS,
    _fmt,
    _json_default,
    _measured,
    add_catalog_args,
    load,
)
from optimizer.errors import RequestError


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "evaluate",
        help="evaluate one design (actuators, propeller, motor, battery) with the model",
        description="Evaluate one design of a catalog: flight time, time constant, price, "
        "mass, hover speed, power, current, inertias and the limit checks.",
    )
    add_catalog_args(p)
    p.add_argument("--actuators", type=int, required=True, metavar="N")
    p.add_argument("--propeller", required=True, metavar="ID")
    p.add_argument("--motor", required=True, metavar="ID")
    p.add_argument("--battery", required=True, metavar="ID")
    add_measured_args(p)
    p.set_defaults(func=handler)


def evaluate(args: argparse.Namespace) -> dict[str, Any]:
    from optimizer.model import MODEL_SOURCES, evaluate_design

    if args.actuators < 3:
        raise RequestError(f"--actuators: expected a count >= 3, got {args.actuators}")
    catalog = load(args.catalog)
    measured = _measured(args, catalog)
    start = time.perf_counter()
    record = evaluate_design(
        catalog,
        args.actuators,
        args.propeller,
        args.motor,
        args.battery,
        args.payload_kg,
        overrides=None if measured is None else measured.overrides,
        esc_mode=None if measured is None else measured.esc_mode,
    )
    record["solve_time_s"] = time.perf_counter() - start
    if measured is not None:
        record.setdefault("sources", {**MODEL_SOURCES, "max_thrust": "not measured"})
        record["measured_store"] = measured.describe()
    if record.get("feasible", True):
        record.pop("reason", None)
    record["catalog"] = catalog.source
    return record


def handler(args: argparse.Namespace) -> int:
    record = evaluate(args)
    if args.json:
        print(json.dumps(record, indent=2, default=_json_default))
        return 0
    from rich.console import Console
    from rich.table import Table

    table = Table(
        title=f"{record['actuators']} actuators, payload {record.get('payload_kg', 0):g} kg",
        title_justify="left",
    )
    table.add_column("Quantity", style="bold")
    table.add_column("Value", justify="right")
    sources = record.get("sources")
    for label, key, fmt in ROWS:
        cell = _fmt(record.get(key), fmt)
        if is_measured(sources, key):
            cell = f"{cell} {MEASURED_MARK}"
        table.add_row(label.replace(" chosen", ""), cell)
    for check in record.get("checks", []):
        unit = f" {check['unit']}" if check["unit"] else ""
        op = "<=" if check["sense"] == "<=" else ">="
        verdict = "ok" if check["ok"] else "VIOLATED"
        table.add_row(
            f"{check['label']}{unit}",
            f"{check['value']:.4g} {op} {check['limit']:.4g}  {verdict}",
        )
    table.add_row("Feasible", "yes" if record["feasible"] else f"no: {record.get('reason')}")
    console = Console(soft_wrap=False)
    console.print(table)
    if sources:
        for key, text in sources.items():
            console.print(f"{key}: {text}", style="dim")
    return 0
