"""``rotorbench optimize``: pick actuators, propeller, motor and battery from a catalog.

Prints a table shaped like Table E.8 of the thesis (rows = quantities, one column
per actuator count, the best column marked) or, with ``--json``, one JSON object
with a ``designs`` list and a ``best`` entry. Exit status: 0 when at least one
actuator count has a feasible design (infeasible columns carry a reason), 3 when
none has (the output still explains why), 2 for bad input.

Every design offered hovers with control margin (``--min-thrust-to-weight``, default 1.2:
a limit of the grid, so the MILP never selects a design below it). ``--thesis-rules`` is
the thesis' model without that check; ``--paper-e-cases`` and ``--method thesis`` (Paper
E's own linearised MILP, which has no thrust limit) imply it and say so.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

from bench.cli_args.option_values import refuse_unused
from bench.cli_args.sizing_args import (
    EXIT_NO_FEASIBLE,
    RULE_FLAGS,
    HoverMargin,
    add_catalog_args,
    add_hover_args,
    add_measured_args,
    add_pack_args,
    add_rule_args,
    hover_margin_from_args,
    json_default,
    measured_from_args,
    packs_from_args,
    rules_from_args,
)
from bench.figures.design_tables import show_table
from bench.store.catalogs import load
from optimizer.cases.paper_e_cases import PAPER_E_CASES
from optimizer.errors import RequestError
from optimizer.solve.objectives import OBJECTIVE_NAMES, Objective, parse_weights, single, weighted
from optimizer.solve.selection_options import (
    meet_roll_rise_option,
    prop_data_option,
    solve,
    solve_packs,
)


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "optimize",
        help="select actuator count, propeller, motor and battery (exact MILP)",
        description="Select the number of actuators, the propeller, the motor and the "
        "battery from a catalog (Papers D and E). Every design is evaluated exactly; "
        "the MILP only chooses. Exit 0 if some actuator count is feasible, 3 if none.",
    )
    add_catalog_args(p)
    p.add_argument(
        "--objective",
        choices=(*OBJECTIVE_NAMES, "weighted"),
        default="flight-time",
        help="what to optimise (default flight-time); 'weighted' needs --weights",
    )
    p.add_argument(
        "--weights",
        default=None,
        help="weighted sum, e.g. flight-time=0.5,price=0.5 (also time-constant, power, "
        "roll-inertia, pitch-inertia, mass)",
    )
    p.add_argument(
        "--normalize",
        choices=("range", "none"),
        default="range",
        help="weighted sums: scale each metric by its range over feasible designs (default) "
        "or add SI values as Paper D does (none)",
    )
    p.add_argument("--actuators", type=int, nargs="+", default=[4, 6, 8], metavar="N")
    p.add_argument("--min-flight-time-min", type=float, default=None, metavar="T")
    p.add_argument("--max-time-constant-ms", type=float, default=None, metavar="T")
    p.add_argument(
        "--method",
        choices=("milp", "exact", "thesis"),
        default="milp",
        help="milp: exact MILP (default); exact: enumeration; thesis: Paper E's "
        "linearised MILP (designs then evaluated exactly)",
    )
    p.add_argument(
        "--paper-e-cases",
        action="store_true",
        help="run Paper E's test cases I-III (max flight time without and with 1.5 kg "
        "payload, min time constant) and print the three tables (Tables E.8-E.10)",
    )
    p.add_argument(
        "--max-roll-rise-ms",
        type=float,
        default=None,
        metavar="T",
        help="keep only designs whose closed-loop 10 deg roll step rises (10-90 %%) within T "
        "ms: the MILP's pick is flown, then the others in objective order (rotorbench fly)",
    )
    p.add_argument(
        "--from-sweep",
        type=Path,
        default=None,
        metavar="SWEEP",
        help="with --max-roll-rise-ms: read the roll rise times from this sweep file "
        "(rotorbench fly --sweep --out SWEEP.parquet) instead of flying; designs it lacks "
        "are not screened (docs/optimizer.md)",
    )
    add_hover_args(p)
    add_measured_args(p)
    add_rule_args(p)
    add_pack_args(p)
    p.add_argument("--prop-data", action="store_true",
                   help="hover speed and power from the APC static C_t(rpm), C_p(rpm) where a "
                   "catalog propeller matches (docs/sizing.md); constants elsewhere")
    p.set_defaults(func=handler)


def run_paper_e_cases(args: argparse.Namespace, catalog: Any, margin: HoverMargin) -> int:
    """The three test cases of Paper E with a progress bar on stderr (the thesis' rules
    unless ``--min-thrust-to-weight`` is given)."""
    from rich.console import Console
    from rich.progress import Progress

    from optimizer.solve.selection import Requirements

    catalog = margin.apply(catalog)
    measured = measured_from_args(args, catalog)
    results = []
    with Progress(console=Console(stderr=True), transient=True) as progress:
        task = progress.add_task("Paper E test cases", total=len(PAPER_E_CASES))
        for case, title, objective, payload in PAPER_E_CASES:
            req = Requirements(
                payload_kg=payload,
                min_flight_time_min=args.min_flight_time_min,
                max_time_constant_ms=args.max_time_constant_ms,
            )
            res = solve(catalog, single(objective), tuple(args.actuators), req, args.method,
                        measured)
            results.append((case, title, res, _hover_warnings(res, catalog, payload)))
            progress.advance(task)
    if args.json:
        cases = [{"case": c, "title": t, **r.to_dict(), "warnings": w}
                 for c, t, r, w in results]
        doc: dict[str, Any] = {"cases": cases, "hover_margin": margin.to_dict(catalog)}
        if measured is not None:
            doc["measured"] = measured.describe()
        print(json.dumps(doc, indent=2, default=json_default))
    else:
        for _, title, res, warnings in results:
            show_table(res, Console(soft_wrap=False).print, title=title)
            for line in warnings:
                print(f"warning: {line}")
        print(margin.describe(catalog))
    return 0 if all(r.any_feasible for _, _, r, _ in results) else EXIT_NO_FEASIBLE


def _hover_warnings(result: Any, catalog: Any, payload_kg: float) -> list[str]:
    """``optimizer.model.sheet.hover_warnings`` for the feasible designs of one result."""
    from optimizer.model.sheet import hover_warnings

    return hover_warnings(catalog, [(d.actuators, d.propeller, d.motor, d.battery)
                                    for d in result.designs if d.feasible], payload_kg)


def build_objective(args: argparse.Namespace) -> Objective:
    if args.objective == "weighted":
        if not args.weights:
            raise RequestError("--objective weighted needs --weights, e.g. flight-time=1,price=1")
        return weighted(parse_weights(args.weights), args.normalize)
    if args.weights:
        raise RequestError("--weights only applies to --objective weighted")
    return single(args.objective)


def handler(args: argparse.Namespace) -> int:
    from optimizer.solve.selection import Requirements

    for n in args.actuators:
        if n < 3:
            raise RequestError(f"--actuators: expected counts >= 3, got {n}")
    if args.method == "thesis" and args.min_thrust_to_weight is not None:
        raise RequestError("--min-thrust-to-weight does not apply to --method thesis (Paper "
                           "E's linearised MILP has no thrust limit); use --method milp")
    if args.paper_e_cases:
        if args.max_roll_rise_ms is not None:
            raise RequestError("--max-roll-rise-ms does not apply to --paper-e-cases")
        # each case brings its own objective and payload; rules, packs and propeller data
        # are not part of Paper E's runs
        refuse_unused(args, ("--objective", "--weights", "--normalize", "--payload-kg",
                             "--flyable", *RULE_FLAGS, "--series", "--parallel",
                             "--prop-data", "--from-sweep"), "with --paper-e-cases")
        implied = "--method thesis" if args.method == "thesis" else "--paper-e-cases"
        margin = hover_margin_from_args(args, implied_by=implied)
        return run_paper_e_cases(args, load(args.catalog, args.current_model), margin)
    objective = build_objective(args)
    screen = _roll_screen(args)
    margin = hover_margin_from_args(
        args, implied_by="--method thesis" if args.method == "thesis" else None)
    catalog = margin.apply(load(args.catalog, args.current_model))
    requirements = Requirements(
        payload_kg=args.payload_kg,
        min_flight_time_min=args.min_flight_time_min,
        max_time_constant_ms=args.max_time_constant_ms,
    )
    measured = measured_from_args(args, catalog)
    rules = rules_from_args(args)
    prop_data = prop_data_option(catalog) if args.prop_data else None
    packs = packs_from_args(args)
    if packs is not None:
        result = solve_packs(catalog, objective, tuple(args.actuators), requirements,
                             args.method, *packs, measured, rules, prop_data)
    else:
        result = solve(catalog, objective, tuple(args.actuators), requirements, args.method,
                       measured, rules, prop_data)
    if args.max_roll_rise_ms is not None:
        if rules is not None or prop_data is not None or args.series is not None:
            raise RequestError("--max-roll-rise-ms does not combine with --flyable, --prop-data "
                               "or --series/--parallel yet (the flown candidates come from the "
                               "plain catalog model)")
        result = meet_roll_rise_option(result, catalog, objective, requirements, args.method,
                                       args.max_roll_rise_ms, measured, screen)
    warnings = _hover_warnings(result, catalog, args.payload_kg)
    if args.json:
        doc = result.to_dict()
        doc["hover_margin"] = margin.to_dict(catalog)
        doc["warnings"] = warnings
        if measured is not None:
            doc["measured"] = measured.describe()
        if rules is not None:
            doc["rules"] = {"enabled": list(rules.enabled), "removed": result.rule_reports}
        if prop_data is not None:
            doc["propeller_data"] = prop_data["report"]
        print(json.dumps(doc, indent=2, default=json_default))
    else:
        from rich.console import Console

        show_table(result, Console(soft_wrap=False).print)
        for d in result.designs:
            info = d.extra.get("flight")
            if info and d.feasible:
                how = (f"flew {info['flown']} design(s)" if "source" not in info else
                       f"from {info['source']}: {info['screened']} screened, "
                       f"{info['not_in_file']} not in the file, "
                       f"{info['not_in_file_better']} of them better")
                print(f"{d.actuators} actuators: roll rise {info['roll_rise_ms']:.0f} ms <= "
                      f"{info['max_roll_rise_ms']:g} ms ({how})")
        if prop_data is not None:
            rep = prop_data["report"]
            print(f"propeller data (APC static): {len(rep['matched'])} matched, missed: "
                  f"{', '.join(rep['missed']) or 'none'}")
        if rules is not None:
            print_rule_reports(result.rule_reports)
        print(margin.describe(catalog))
        for line in warnings:
            print(f"warning: {line}")
    return 0 if result.any_feasible else EXIT_NO_FEASIBLE



def _roll_screen(args: argparse.Namespace) -> Any:
    """The sweep file's roll rise times (``--from-sweep``), read and checked before any
    solve; None without it."""
    if args.from_sweep is None:
        return None
    if args.max_roll_rise_ms is None:
        refuse_unused(args, ("--from-sweep",), "without --max-roll-rise-ms")
        raise RequestError("--from-sweep needs --max-roll-rise-ms")  # a library caller
    from optimizer.sweep.sweep_screen import roll_screen

    return roll_screen(args.from_sweep, args.payload_kg)


def print_rule_reports(reports: list[dict[str, Any]]) -> None:
    """One line per actuator count: designs each rule removed (alone / in turn)."""
    for r in reports:
        parts = ", ".join(f"{k} {r['removed_alone'][k]}/{r['removed_in_turn'][k]}"
                          for k in r["removed_alone"])
        print(f"rules, {r['actuators']} actuators: {r['physically_feasible']} of "
              f"{r['designs']} designs within the limits, {r['flyable']} flyable; removed "
              f"(alone/in turn): {parts}")
