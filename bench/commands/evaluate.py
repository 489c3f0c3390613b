"""``rotorbench evaluate``: what does my build do? One given design, like an eCalc sheet.

Reports the same keys as an ``optimize --json`` design entry for one actuator count,
propeller, motor and battery (catalog ids, or free-form datasheet numbers without a
catalog), every limit check, and what eCalc shows: maximum thrust, thrust-to-weight,
hover throttle, efficiency, the partial-load table, the Shepherd-model flight time beside
the thesis' constant-voltage one, C-rate checks and limit margins. ``feasible`` means what
``optimize`` would offer: the hover margin (``--min-thrust-to-weight``, default 1.2) is one
of the limits unless ``--thesis-rules``. Exit 0 whether or not the design is feasible
(``feasible`` and ``reason`` say), 2 for bad input.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path
from typing import Any

from bench.cli_args.sizing_args import (
    add_catalog_args,
    add_hover_args,
    add_measured_args,
    hover_margin_from_args,
    json_default,
    measured_from_args,
)
from bench.figures.design_tables import MEASURED_MARK, ROWS, format_cell
from bench.paths.outputs import check_figure_path
from bench.store.catalogs import load, with_current_model
from bench.store.measured_constants import is_measured
from optimizer.errors import RequestError


def register(subparsers: argparse._SubParsersAction) -> None:
    from optimizer.catalogs.freeform import FIELDS

    p = subparsers.add_parser(
        "evaluate",
        help="evaluate one design (catalog ids or free-form parts) like an eCalc sheet",
        description="Evaluate one design: flight time (thesis and battery model), time "
        "constant, price, mass, hover, full throttle, partial load, limit checks. Give "
        "catalog ids (--propeller/--motor/--battery) or free-form parts (--motor-kv ...).",
    )
    add_catalog_args(p)
    p.add_argument("--actuators", type=int, required=True, metavar="N")
    p.add_argument("--propeller", metavar="ID")
    p.add_argument("--motor", metavar="ID")
    p.add_argument("--battery", metavar="ID")
    free = p.add_argument_group("free-form parts (instead of catalog ids)")
    for part, column, flag, required in FIELDS:
        need = "required" if required else "optional"
        free.add_argument(flag, type=float, default=None, metavar="X",
                          help=f"{part} {column} ({need} for a free-form design)")
    p.add_argument("--cutoff-cell-v", type=float, default=None, metavar="V",
                   help="battery model: cut-off voltage per cell (default 3.3)")
    p.add_argument("--prop-data", action="store_true",
                   help="propeller Ct, Cp against rpm from the APC static data where a "
                   "catalog propeller matches (shown beside the constant coefficients)")
    p.add_argument("--plot", type=Path, default=None, metavar="PNG",
                   help="draw the partial-load curves to this PNG")
    add_measured_args(p)
    add_hover_args(p)
    p.set_defaults(func=handler)


def _catalog_and_ids(args: argparse.Namespace) -> tuple[Any, tuple[str, str, str]]:
    from optimizer.catalogs.freeform import freeform_catalog, given

    margin = hover_margin_from_args(args)
    ids = (args.propeller, args.motor, args.battery)
    if given(vars(args)):
        if any(i is not None for i in ids):
            raise RequestError("evaluate: give catalog ids (--propeller/--motor/--battery) or "
                               "free-form parts (--motor-kv ...), not both")
        constants = load(args.catalog).constants if args.catalog is not None else None
        catalog = with_current_model(freeform_catalog(vars(args), constants), args.current_model)
        return margin.apply(catalog), ("prop", "motor", "battery")
    missing = [f for f, i in zip(("--propeller", "--motor", "--battery"), ids, strict=True)
               if i is None]
    if missing:
        raise RequestError(f"evaluate: missing {', '.join(missing)} (or give free-form parts)")
    catalog = margin.apply(load(args.catalog, args.current_model))
    return _with_pack(catalog, args.battery), (args.propeller, args.motor, args.battery)


def _with_pack(catalog: Any, battery_id: str) -> Any:
    """A pack id of ``optimize --series`` (``B1-4S3P``: 4S3P of B1's cell) names a pack
    built from the catalog's cell; any other id is looked up as it is."""
    import re

    from optimizer.solve.packs import with_packs

    m = re.fullmatch(r"(.+)-(\d+)S(\d+)P", str(battery_id))
    if battery_id in catalog.battery_ids or not m or m.group(1) not in catalog.battery_ids:
        return catalog
    return with_packs(catalog, (int(m.group(2)),), (int(m.group(3)),))


def evaluate(args: argparse.Namespace) -> dict[str, Any]:
    from optimizer.catalogs.freeform import NO_LIMIT
    from optimizer.model import battery as bat
    from optimizer.model.design_model import MODEL_SOURCES, evaluate_design, single_design_catalog
    from optimizer.model.sheet import design_sheet

    if args.actuators < 3:
        raise RequestError(f"--actuators: expected a count >= 3, got {args.actuators}")
    curve = bat.DEFAULT_CELL
    if args.cutoff_cell_v is not None:
        if not 0 < args.cutoff_cell_v < curve.full_v:
            raise RequestError(f"--cutoff-cell-v: expected 0 < V < {curve.full_v:g}, "
                               f"got {args.cutoff_cell_v:g}")
        curve = bat.CellCurve(cutoff_v=args.cutoff_cell_v)
    catalog, (pid, mid, bid) = _catalog_and_ids(args)
    measured = measured_from_args(args, catalog)
    start = time.perf_counter()
    record = evaluate_design(
        catalog,
        args.actuators,
        pid,
        mid,
        bid,
        args.payload_kg,
        overrides=None if measured is None else measured.overrides,
        esc_mode=None if measured is None else measured.esc_mode,
    )
    single = single_design_catalog(catalog, pid, mid, bid)
    record.update(design_sheet(single, record, curve))
    record["rules"] = flyable_rules(single, args.actuators, args.payload_kg)
    if args.prop_data:
        from optimizer.model.propdata import compare_for_design

        record["propeller_data"] = compare_for_design(single, record, curve)
    # limits a free-form user did not give are not checks
    record["checks"] = [c for c in record["checks"] if c["limit"] < NO_LIMIT]
    record["limit_margins"] = [m for m in record["limit_margins"] if m["limit"] < NO_LIMIT]
    record["solve_time_s"] = time.perf_counter() - start
    if measured is not None:
        record.setdefault("sources", {**MODEL_SOURCES, "max_thrust": "not measured"})
        record["measured_store"] = measured.describe()
    if record.get("feasible", True):
        record.pop("reason", None)
    record["catalog"] = catalog.source
    return record


def flyable_rules(single: Any, n: int, payload_kg: float) -> list[dict[str, Any]]:
    """The flyable-design rules (optimizer.model.flyable defaults) on this design, for reading:
    ``feasible`` stays the catalog's limits; ``optimize --flyable`` enforces them."""
    import numpy as np

    from optimizer.model.design_model import evaluate_grid
    from optimizer.model.flyable import Rules, rule_checks, rule_of

    grid = evaluate_grid(single, n, payload_kg)
    out = []
    for c in rule_checks(single, grid, Rules()):
        value = float(np.ravel(np.broadcast_to(c.value, grid.shape))[0])
        limit = float(np.ravel(np.broadcast_to(c.limit, grid.shape))[0])
        margin = float(np.ravel(np.broadcast_to(c.margin(), grid.shape))[0])
        out.append({"rule": rule_of(c), "label": c.label.split(": ", 1)[1], "unit": c.unit,
                    "value": value, "limit": limit, "sense": c.sense, "ok": margin >= 0})
    return out


def handler(args: argparse.Namespace) -> int:
    if args.plot is not None:  # refused before the work, not after it
        check_figure_path(args.plot)
    record = evaluate(args)
    if args.plot is not None:
        from bench.figures.sizing_figures import partial_load_figure

        partial_load_figure(record, args.plot)
    if args.json:
        print(json.dumps(record, indent=2, default=json_default))
        return 0
    print_sheet(record)
    if args.plot is not None:
        print(f"partial-load plot: {args.plot}")
    return 0


def print_sheet(record: dict[str, Any]) -> None:
    """The eCalc-like text sheet: design, hover and full throttle, battery, partial load."""
    from rich.console import Console
    from rich.table import Table

    console = Console(soft_wrap=False)
    table = Table(
        title=f"{record['actuators']} actuators, payload {record.get('payload_kg', 0):g} kg",
        title_justify="left",
    )
    table.add_column("Quantity", style="bold")
    table.add_column("Value", justify="right")
    sources = record.get("sources")
    for label, key, fmt in ROWS:
        cell = format_cell(record.get(key), fmt)
        if is_measured(sources, key):
            cell = f"{cell} {MEASURED_MARK}"
        table.add_row(label.replace(" chosen", ""), cell)
    table.add_row("Feasible", "yes" if record["feasible"] else f"no: {record.get('reason')}")
    console.print(table)

    bm = record["battery_model"]
    sheet = Table(title="Like eCalc", title_justify="left")
    sheet.add_column("Quantity", style="bold")
    sheet.add_column("Value", justify="right")
    rows = [
        ("Max thrust per actuator (N)", f"{record['max_thrust_n']:.2f}"),
        ("Thrust-to-weight", f"{record['thrust_to_weight']:.2f}"),
        ("Hover throttle (%)", f"{record['hover_throttle_pct']:.0f}"),
        ("Hover efficiency (g/W)", f"{record['efficiency_g_per_w']:.2f}"),
        ("Current model (--current-model)", record["current_model"]),
        ("Hover battery power (W)", f"{record['hover_electric_power_w']:.1f}"),
        ("Hover battery current (A)", f"{record['hover_battery_current_a']:.2f}"),
        *((f"{name} model: A per actuator / min",
           f"{m['current_per_actuator_a']:.2f} / {m['flight_time_min']:.1f}")
          for name, m in record["current_models"].items()),
        ("Full throttle: rpm", f"{record['max_rpm']:.0f}"),
        ("Full throttle: motor current (A)", f"{record['max_motor_current_a']:.2f}"),
        ("Full throttle: battery current (A)", f"{record['max_battery_current_a']:.1f}"),
        ("Full throttle: tip speed (m/s)", f"{record['tip_speed_max_m_s']:.0f}"),
        ("Flight time, thesis (min) [1]", f"{bm['thesis_flight_time_min']:.1f}"),
        ("Flight time, battery model (min) [2]", f"{bm['flight_time_min']:.1f}"),
        ("Usable capacity (%)", f"{bm['usable_capacity_pct']:.0f}"),
        ("Pack voltage start -> end (V)",
         f"{bm['start_voltage_v']:.2f} -> {bm['end_voltage_v']:.2f}"),
        ("Hover current start -> end (A)",
         f"{bm['start_current_a']:.2f} -> {bm['end_current_a']:.2f}"),
    ]
    for label, value in rows:
        sheet.add_row(label, value)
    for m in record["limit_margins"]:
        unit = f" {m['unit']}" if m["unit"] else ""
        op = "<=" if m["sense"] == "<=" else ">="
        pct = "" if m["margin_pct"] is None else f", margin {m['margin_pct']:.0f} %"
        verdict = "ok" if m["ok"] else "VIOLATED"
        sheet.add_row(f"{m['label']}{unit}",
                      f"{m['value']:.4g} {op} {m['limit']:.4g}{pct}  {verdict}")
    console.print(sheet)
    console.print(f"[1] {bm['thesis_label']}\n[2] {bm['label']}", style="dim")
    for name, m in record["current_models"].items():
        console.print(f"current model {name}: {m['label']}", style="dim")
    rules = Table(title="Flyable-design rules (optimize --flyable enforces them)",
                  title_justify="left")
    for head in ("Rule", "Quantity", "Value", "Limit", ""):
        rules.add_column(head, justify="left" if head in ("Rule", "Quantity") else "right")
    for r in record.get("rules", []):
        op = "<=" if r["sense"] == "<=" else ">="
        rules.add_row(r["rule"], r["label"], f"{r['value']:.4g} {r['unit']}",
                      f"{op} {r['limit']:.4g}", "ok" if r["ok"] else "FAILS")
    console.print(rules)

    part = Table(title="Partial load (per actuator; current from the battery)",
                 title_justify="left")
    for head in ("Throttle %", "Thrust N", "Current A", "Power W", "rpm", "g/W"):
        part.add_column(head, justify="right")
    for r in record["partial_load"]:
        part.add_row(f"{r['throttle_pct']:.0f}", f"{r['thrust_n']:.2f}", f"{r['current_a']:.2f}",
                     f"{r['power_w']:.1f}", f"{r['rpm']:.0f}", f"{r['efficiency_g_per_w']:.2f}")
    console.print(part)
    pdata = record.get("propeller_data")
    if pdata:
        console.print(f"Propeller data: {pdata['summary']}")
    if sources:
        for key, text in sources.items():
            console.print(f"{key}: {text}", style="dim")
