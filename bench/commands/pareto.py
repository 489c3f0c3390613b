"""``rotorbench pareto``: the exact front of two objectives (e.g. flight time vs time constant).

Per actuator count the epsilon-constraint MILP (``optimizer.solve.pareto``) walks the
non-dominated designs; the fronts of several counts are merged by dominance. Every design
hovers with the margin of ``--min-thrust-to-weight`` (default 1.2; ``--thesis-rules``
drops it), a check of the grid the front is solved on. ``--check``
also enumerates every design and says whether the two fronts agree. ``front`` lists
designs with the keys of an ``optimize --json`` design. ``--from SWEEP.parquet`` draws the
front of any two columns of a closed-loop sweep file instead (``optimizer.sweep.sweep_file``:
objectives, ``roll-rise``-style aliases, raw columns; no catalog, no MILP). Exit 0 with a
front, 3 when no design is feasible, 2 for bad input.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path
from typing import Any

import numpy as np

from bench.cli_args.option_values import given_options, refuse_unused
from bench.cli_args.sizing_args import (
    EXIT_NO_FEASIBLE,
    RULE_FLAGS,
    add_catalog_args,
    add_hover_args,
    add_rule_args,
    hover_margin_from_args,
    json_default,
    rules_from_args,
)
from bench.paths.outputs import check_figure_path
from bench.store.catalogs import load
from optimizer.errors import RequestError

#: Most points drawn in grey on the plot (an even subsample beyond this).
PLOT_CLOUD_MAX = 200_000


def register(subparsers: argparse._SubParsersAction) -> None:
    from optimizer.solve.objectives import METRICS

    p = subparsers.add_parser(
        "pareto",
        help="exact Pareto front of two objectives (epsilon-constraint MILP)",
        description="The non-dominated designs of two objectives (any of "
        f"{', '.join(METRICS)}), exact: an epsilon-constraint MILP per actuator count, "
        "fronts merged by dominance. With --from SWEEP.parquet: the exact front of any two "
        "columns of a closed-loop sweep file (docs/optimizer.md).",
    )
    add_catalog_args(p)
    p.add_argument("--actuators", type=int, nargs="+", default=[4, 6, 8], metavar="N",
                   help="actuator counts (default 4 6 8; with --from: keep only these rows)")
    axis = (f"one of {', '.join(METRICS)}; with --from also <maneuver>-rise|-overshoot|"
            "-settling|-saturation[-pNN] (e.g. roll-rise) or a numeric column, minimised "
            "unless written max:NAME")
    p.add_argument("--x", default="flight-time", metavar="NAME", help=f"x objective: {axis}")
    p.add_argument("--y", default="time-constant", metavar="NAME", help="y objective (as --x)")
    p.add_argument("--from", dest="source", type=Path, default=None, metavar="SWEEP",
                   help="the front of a closed-loop sweep file (rotorbench fly --sweep --out "
                   "SWEEP.parquet) instead of a catalog")
    p.add_argument("--method", choices=("milp", "exact"), default="milp",
                   help="milp: epsilon-constraint MILP (default); exact: enumeration")
    p.add_argument("--check", action="store_true",
                   help="also enumerate and report whether both fronts agree")
    p.add_argument("--plot", type=Path, default=None, metavar="PNG",
                   help="draw the front over all feasible designs (grey) to this PNG")
    add_hover_args(p)
    add_rule_args(p)
    p.set_defaults(func=handler)


def compute(args: argparse.Namespace) -> dict[str, Any]:
    from optimizer.model.design_model import evaluate_grid
    from optimizer.solve import pareto
    from optimizer.solve.objectives import METRICS, single
    from optimizer.solve.selection import DesignResult, _design_at

    if args.x == args.y:
        raise RequestError(f"--x and --y are both {args.x}; give two different objectives")
    for flag, name in (("--x", args.x), ("--y", args.y)):
        if name not in METRICS:
            raise RequestError(f"{flag} {name}: expected one of {', '.join(METRICS)} "
                               "(closed-loop figures and other columns: --from SWEEP.parquet)")
    for n in args.actuators:
        if n < 3:
            raise RequestError(f"--actuators: expected counts >= 3, got {n}")
    margin = hover_margin_from_args(args)
    catalog = margin.apply(load(args.catalog, args.current_model))
    rules = rules_from_args(args)
    build: Any = evaluate_grid
    if rules is not None:
        from optimizer.model.flyable import FlyableBuilder

        build = FlyableBuilder(rules)
    ox, oy = single(args.x), single(args.y)
    per, candidates, cloud_x, cloud_y = [], [], [], []
    for n in dict.fromkeys(args.actuators):
        t0 = time.perf_counter()
        grid = build(catalog, n, args.payload_kg)
        grid_time = time.perf_counter() - t0
        ok = grid.feasible()
        cx, cy = ox.cost(grid), oy.cost(grid)
        solver = pareto.milp_front if args.method == "milp" else pareto.enumerate_front
        res = solver(cx, cy, ok)
        entry: dict[str, Any] = {
            "actuators": n, "points": len(res.indices), "method": res.method,
            "solves": res.solves, "time_s": res.time_s, "grid_time_s": grid_time,
            "feasible_designs": int(ok.sum()), "designs": int(np.prod(grid.shape)),
        }
        if args.check:
            other = (pareto.enumerate_front if args.method == "milp" else pareto.milp_front)(
                cx, cy, ok)
            entry["check_method"] = other.method
            entry["check_time_s"] = other.time_s
            entry["check_agrees"] = other.indices.tolist() == res.indices.tolist()
        per.append(entry)
        for flat in res.indices:
            i, j, k = (int(v) for v in np.unravel_index(flat, grid.shape))
            idx = (i, j, k)
            d = DesignResult(
                actuators=n, feasible=True, **_design_at(grid, idx), cost=float(cx.flat[flat]),
                solve_time_s=res.time_s, grid_time_s=grid_time, method=res.method,
                status="optimal", n_candidates=int(ok.sum()), n_designs=int(np.prod(grid.shape)),
            )
            candidates.append((float(cx.flat[flat]), float(cy.flat[flat]), d))
        metric_x, metric_y = ox.terms[0][0].metric, oy.terms[0][0].metric
        cloud_x.append(grid.metrics[metric_x][ok])
        cloud_y.append(grid.metrics[metric_y][ok])
    keep = pareto.merge_fronts([(x, y) for x, y, _ in candidates])
    front = [candidates[i][2].to_dict() for i in keep]
    for d in front:  # solve_time_s here: the whole front of its actuator count
        d.pop("objective_cost", None)
    spec_x, spec_y = ox.terms[0][0], oy.terms[0][0]
    from optimizer.model.sheet import hover_warnings

    warnings = hover_warnings(catalog, [(d["actuators"], d["propeller"], d["motor"],
                                         d["battery"]) for d in front], args.payload_kg)
    return {
        "x": args.x, "y": args.y,
        "x_key": spec_x.metric, "y_key": spec_y.metric,
        "x_sense": spec_x.sense, "y_sense": spec_y.sense,
        "x_label": f"{spec_x.label} ({spec_x.unit})" if spec_x.unit else spec_x.label,
        "y_label": f"{spec_y.label} ({spec_y.unit})" if spec_y.unit else spec_y.label,
        "catalog": catalog.source, "catalog_name": Path(str(catalog.source)).name,
        "actuators": list(dict.fromkeys(args.actuators)), "payload_kg": args.payload_kg,
        "method": args.method, "front": front, "per_actuator": per, "warnings": warnings,
        "hover_margin": margin.to_dict(catalog), "hover_margin_text": margin.describe(catalog),
        "rules": None if rules is None else {"enabled": list(rules.enabled),
                                              "removed": [r.to_dict() for r in build.reports]},
        "_cloud": (np.concatenate(cloud_x), np.concatenate(cloud_y)),
    }


#: Options of the catalog and the MILP, which a sweep file has already decided.
CATALOG_ONLY = ("--catalog", "--payload-kg", "--current-model", "--method", "--check",
                "--min-thrust-to-weight", "--thesis-rules", "--flyable", *RULE_FLAGS)


def compute_from_file(args: argparse.Namespace) -> dict[str, Any]:
    """``compute``'s document for the rows of a sweep file (``pareto --from``)."""
    from optimizer.sweep.sweep_file import front, open_sweep

    refuse_unused(args, CATALOG_ONLY, "with --from (the sweep file holds the designs and "
                  "their numbers)")
    sweep = open_sweep(args.source)
    only = list(dict.fromkeys(args.actuators)) if given_options(args, "--actuators") else None
    res = front(sweep, args.x, args.y, only)
    catalog = sweep.spec.get("catalog")
    name = Path(str(catalog)).name if isinstance(catalog, str) else sweep.path.name
    return {
        "x": args.x, "y": args.y, "x_key": res.x.column, "y_key": res.y.column,
        "x_label": res.x.label, "y_label": res.y.label,
        "x_sense": res.x.sense, "y_sense": res.y.sense,
        "source": str(sweep.path), "catalog": catalog, "catalog_name": name,
        "actuators": res.actuators, "method": "sweep", "front": res.front,
        "rows": res.rows, "considered": res.considered, "left_out": res.left_out.to_dict(),
        "left_out_text": res.left_out.text(), "sweep": sweep.spec,
        "hover_margin_text": _sweep_margin_text(sweep.spec),
        "_cloud": res.cloud, "_cloud_label": "flown designs that hover",
    }


def _sweep_margin_text(spec: dict[str, Any]) -> str | None:
    """The hover margin the sweep was flown under (its spec's ``options.hover_margin``), as
    ``pareto`` says its own: a front of a ``--thesis-rules`` sweep may hold designs below
    the default margin (rows that cannot hover are left out)."""
    options = spec.get("options")
    margin = options.get("hover_margin") if isinstance(options, dict) else None
    if not isinstance(margin, dict):
        return None
    source, ratio = margin.get("source", "?"), margin.get("min_thrust_to_weight")
    if margin.get("thesis_rules"):
        line = (f"thesis rules (the sweep's {source}): no hover margin, designs that cannot "
                "hover left out")
        return line + (f"; the catalog's own min_thrust_to_weight {ratio:g} applied"
                       if isinstance(ratio, (int, float)) else "")
    if not isinstance(ratio, (int, float)):
        return None
    return (f"hover margin (the sweep's, {source}): every design reaches full-throttle "
            f"thrust-to-weight >= {ratio:g}")


def handler(args: argparse.Namespace) -> int:
    if args.plot is not None:  # refused before the work, not after it
        check_figure_path(args.plot, inputs=(args.source,))
    if args.source is not None:
        return _report(args, compute_from_file(args))
    return _report(args, compute(args))


def _report(args: argparse.Namespace, doc: dict[str, Any]) -> int:
    """Plot, then print the document (JSON or a table and its notes)."""
    if args.plot is not None:
        from bench.figures.sizing_figures import pareto_figure

        cx, cy = doc["_cloud"]
        step = max(1, -(-cx.size // PLOT_CLOUD_MAX))
        pareto_figure({**doc, "_cloud": (cx[::step], cy[::step])}, args.plot)
    doc.pop("_cloud")
    doc.pop("_cloud_label", None)
    text = doc.pop("hover_margin_text", None)
    if args.json:
        print(json.dumps(doc, indent=2, default=json_default))
    else:
        print_front(doc)
        if args.plot is not None:
            print(f"plot: {args.plot}")
        if text:
            print(text)
        for line in doc.get("warnings", ()):
            print(f"warning: {line}")
    return 0 if doc["front"] else EXIT_NO_FEASIBLE


def print_front(doc: dict[str, Any]) -> None:
    from rich.console import Console
    from rich.table import Table

    where = (f"from {doc['source']}" if "source" in doc else
             f"payload {doc['payload_kg']:g} kg, method {doc['method']}")
    table = Table(title=f"Pareto front: {doc['x']} vs {doc['y']}, {where}",
                  title_justify="left")
    for head in ("N", "Propeller", "Motor", "Battery", doc["x_label"], doc["y_label"],
                 "Price", "Mass (kg)"):
        table.add_column(head, justify="right")
    for d in doc["front"]:
        table.add_row(str(d["actuators"]), d["propeller"], d["motor"], d["battery"],
                      *(_number(d.get(k), f) for k, f in ((doc["x_key"], ".4g"),
                                                          (doc["y_key"], ".4g"),
                                                          ("price", ".2f"),
                                                          ("total_mass_kg", ".3f"))))
    console = Console(soft_wrap=False)
    console.print(table)
    if "source" in doc:
        console.print(f"{len(doc['front'])} points from {doc['considered']} of "
                      f"{doc['rows']} rows; {doc['left_out_text']}")
    for e in doc.get("per_actuator", ()):
        line = (f"{e['actuators']} actuators: {e['points']} points from {e['feasible_designs']} "
                f"feasible designs, {e['solves']} MILP solves, {e['time_s']:.3f} s")
        if "check_agrees" in e:
            verdict = "agrees" if e["check_agrees"] else "DISAGREES"
            line += f"; {e['check_method']} {verdict} ({e['check_time_s']:.3f} s)"
        console.print(line)
    if not doc["front"]:
        console.print("No feasible design.", style="bold red")


def _number(value: Any, fmt: str) -> str:
    return "-" if value is None else format(value, fmt)
