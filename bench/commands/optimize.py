"""``rotorbench optimize``: pick actuators, propeller, motor and battery from a catalog.

Prints a table shaped like Table E.8 of the thesis (rows = quantities, one column
per actuator count, the best column marked) or, with ``--json``, one JSON object
with a ``designs`` list and a ``best`` entry. Exit status: 0 when at least one
actuator count has a feasible design (infeasible columns carry a reason), 3 when
none has (the output still explains why), 2 for bad input.
"""

from __future__ import annotations

import argparse
import json
import math
import os
from pathlib import Path
from typing import Any

from bench.commands._measured import add_measured_args, is_measured, load_measured_set
from optimizer.errors import CatalogError, RequestError
from optimizer.objectives import OBJECTIVE_NAMES, Objective, parse_weights, single, weighted

#: Exit status when no requested actuator count has a feasible design.
EXIT_NO_FEASIBLE = 3

#: Marks a table cell whose number was measured on the bench (--measured).
MEASURED_MARK = "(m)"

#: Table rows: (label, key, format).
ROWS: tuple[tuple[str, str, str], ...] = (
    ("Propeller chosen", "propeller", "s"),
    ("Motor chosen", "motor", "s"),
    ("Battery chosen", "battery", "s"),
    ("Time constant (ms)", "time_constant_ms", ".0f"),
    ("Flight time (min)", "flight_time_min", ".1f"),
    ("Price", "price", ".2f"),
    ("Total mass (kg)", "total_mass_kg", ".3f"),
    ("Hover speed (rpm)", "hover_rpm", ".0f"),
    ("Propeller power (W)", "propeller_power_w", ".1f"),
    ("Battery current (A)", "current_a", ".2f"),
    ("Roll inertia (kg m^2)", "roll_inertia_kgm2", ".4f"),
    ("Pitch inertia (kg m^2)", "pitch_inertia_kgm2", ".4f"),
)


SHIPPED_CATALOGS = Path(__file__).resolve().parents[2] / "fixtures" / "catalogs"


def default_catalog() -> Path:
    """fixtures/catalogs/thesis-e of the source tree (or $ROTORBENCH_CATALOG)."""
    env = os.environ.get("ROTORBENCH_CATALOG")
    if env:
        return _shipped_name(Path(env))
    return SHIPPED_CATALOGS / "thesis-e"


def _shipped_name(path: Path) -> Path:
    """A bare name that is no folder here but a shipped catalog (``thesis-d``) means it."""
    if not path.exists() and len(path.parts) == 1 and (SHIPPED_CATALOGS / path.name).is_dir():
        return SHIPPED_CATALOGS / path.name
    return path


def load(path: Path | None) -> Any:
    """Load a catalog; a missing default catalog is a clear error, not a traceback."""
    from optimizer.catalog import load_catalog

    folder = _shipped_name(path) if path is not None else default_catalog()
    if path is None and not folder.is_dir():
        if os.environ.get("ROTORBENCH_CATALOG"):
            raise CatalogError(f"ROTORBENCH_CATALOG={os.environ['ROTORBENCH_CATALOG']}: not a "
                               "catalog folder or a shipped catalog name")
        raise CatalogError(
            f"{folder}: default catalog not found (installed without the source tree?); "
            "pass --catalog DIR or set ROTORBENCH_CATALOG"
        )
    return load_catalog(folder)


def add_catalog_args(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--catalog",
        type=Path,
        default=None,
        help="catalog folder, or the name of a shipped one (thesis-e, thesis-d; "
             "default: fixtures/catalogs/thesis-e)",
    )
    p.add_argument("--payload-kg", type=float, default=0.0, help="payload mass (default 0)")
    p.add_argument("--json", action="store_true", help="print one JSON object")


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
    add_measured_args(p)
    add_rule_args(p)
    p.add_argument("--series", default=None, metavar="S",
                   help="choose cells in series too, e.g. 2-6 (the catalog's batteries read "
                   "as cells, docs/sizing.md)")
    p.add_argument("--parallel", default=None, metavar="P",
                   help="with --series: parallel strings, e.g. 1-4 (default 1)")
    p.add_argument("--prop-data", action="store_true",
                   help="hover speed and power from the APC static C_t(rpm), C_p(rpm) where a "
                   "catalog propeller matches (docs/sizing.md); constants elsewhere")
    p.set_defaults(func=handler)


def add_rule_args(p: argparse.ArgumentParser) -> None:
    """``--flyable`` and its rule switches (optimizer.flyable)."""
    from optimizer.flyable import RULE_NAMES, Rules

    d = Rules()
    g = p.add_argument_group("flyable-design rules (docs/sizing.md)")
    g.add_argument("--flyable", action="store_true",
                   help=f"apply the rules {', '.join(RULE_NAMES)} and report what each removes")
    g.add_argument("--no-rule", action="append", default=[], choices=RULE_NAMES,
                   metavar="NAME", help="switch one rule off (repeatable)")
    g.add_argument("--tip-speed-max", type=float, default=d.tip_speed_m_s, metavar="M_S",
                   help=f"rule tip-speed: full-throttle tip speed limit (default "
                   f"{d.tip_speed_m_s:g} m/s)")
    g.add_argument("--max-wheelbase-m", type=float, default=d.max_wheelbase_m, metavar="M",
                   help=f"rule frame: motor-to-motor diagonal limit (default "
                   f"{d.max_wheelbase_m:g} m)")
    g.add_argument("--hover-throttle", type=float, nargs=2, default=d.hover_throttle_pct,
                   metavar=("LO", "HI"), help="rule hover-throttle: band in percent "
                   "(default 30 70)")
    g.add_argument("--rule-max-time-constant-ms", type=float, default=d.max_time_constant_ms,
                   metavar="MS", help=f"rule response: time-constant limit (default "
                   f"{d.max_time_constant_ms:g} ms)")


def rules_from_args(args: argparse.Namespace) -> Any:
    """The ``Rules`` of ``--flyable`` (None without it)."""
    from optimizer.flyable import RULE_NAMES, Rules

    if not getattr(args, "flyable", False):
        if getattr(args, "no_rule", None):
            raise RequestError("--no-rule only applies with --flyable")
        return None
    return Rules(
        enabled=tuple(r for r in RULE_NAMES if r not in args.no_rule),
        tip_speed_m_s=args.tip_speed_max,
        max_wheelbase_m=args.max_wheelbase_m,
        hover_throttle_pct=tuple(args.hover_throttle),
        max_time_constant_ms=args.rule_max_time_constant_ms,
    ).validate()


#: Paper E section 4: (case, title, objective, payload kg).
PAPER_E_CASES: tuple[tuple[str, str, str, float], ...] = (
    ("I", "Test Case I: longest flight time, no payload (Table E.8)", "flight-time", 0.0),
    ("II", "Test Case II: longest flight time, 1.5 kg payload (Table E.9)", "flight-time", 1.5),
    ("III", "Test Case III: fastest motor response, no payload (Table E.10)", "time-constant", 0.0),
)


def run_paper_e_cases(args: argparse.Namespace, catalog: Any) -> int:
    """The three test cases of Paper E with a progress bar on stderr."""
    from rich.console import Console
    from rich.progress import Progress

    from optimizer.selection import Requirements

    measured = _measured(args, catalog)
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
            results.append((case, title, res))
            progress.advance(task)
    if args.json:
        cases = [{"case": c, "title": t, **r.to_dict()} for c, t, r in results]
        doc: dict[str, Any] = {"cases": cases}
        if measured is not None:
            doc["measured"] = measured.describe()
        print(json.dumps(doc, indent=2, default=_json_default))
    else:
        for _, title, res in results:
            print_table(res, title=title)
    return 0 if all(r.any_feasible for _, _, r in results) else EXIT_NO_FEASIBLE


def _measured(args: argparse.Namespace, catalog: Any) -> Any:
    if getattr(args, "measured", None) is None:
        if getattr(args, "esc_mode", None) is not None:
            raise RequestError("--esc-mode only applies with --measured")
        return None
    return load_measured_set(args.measured, catalog, args.esc_mode)


def prop_data_build(catalog: Any) -> tuple[Any, Any]:
    """``--prop-data``: (build_grid with the APC C_t(rpm), C_p(rpm), match report)."""
    from functools import partial

    from optimizer.design_model import evaluate_grid
    from optimizer.propdata import catalog_curves, data_folder, load_curves, match_report

    table = catalog_curves(catalog, load_curves(data_folder()))
    return (partial(evaluate_grid, coefficients=table.coefficients),
            {**match_report(catalog, table), "coefficients": table.coefficients})


def solve(catalog: Any, objective: Objective, actuators: tuple[int, ...], requirements: Any,
          method: str, measured: Any = None, rules: Any = None,
          prop_data: dict[str, Any] | None = None) -> Any:
    """``optimizer.selection.optimize``, with the measured overrides when given (then every
    design carries ``sources``) and the flyable-design rules when given (then the result
    carries ``rule_reports``)."""
    from optimizer.selection import optimize

    if method == "thesis" and (measured is not None or rules is not None):
        raise RequestError("--measured and --flyable work with --method milp or exact (the "
                           "thesis formulation linearises the datasheet model)")
    if prop_data is not None and (measured is not None or method == "thesis"):
        raise RequestError("--prop-data works with --method milp or exact, without --measured")
    build = None if measured is None else measured.build_grid
    coefficients = None
    if prop_data is not None:
        build, coefficients = prop_data["build"], prop_data["coefficients"]
    builder = None
    if rules is not None:
        from optimizer.flyable import FlyableBuilder

        build = builder = FlyableBuilder(rules, build, coefficients=coefficients)
    result = optimize(catalog, objective, actuators, requirements, method, build_grid=build)
    if measured is not None:
        measured.annotate(result)
    if builder is not None:
        result.rule_reports = [r.to_dict() for r in builder.reports]
    return result


def build_objective(args: argparse.Namespace) -> Objective:
    if args.objective == "weighted":
        if not args.weights:
            raise RequestError("--objective weighted needs --weights, e.g. flight-time=1,price=1")
        return weighted(parse_weights(args.weights), args.normalize)
    if args.weights:
        raise RequestError("--weights only applies to --objective weighted")
    return single(args.objective)


def handler(args: argparse.Namespace) -> int:
    from optimizer.selection import Requirements

    for n in args.actuators:
        if n < 3:
            raise RequestError(f"--actuators: expected counts >= 3, got {n}")
    if args.paper_e_cases:
        if args.max_roll_rise_ms is not None:
            raise RequestError("--max-roll-rise-ms does not apply to --paper-e-cases")
        return run_paper_e_cases(args, load(args.catalog))
    objective = build_objective(args)
    catalog = load(args.catalog)
    requirements = Requirements(
        payload_kg=args.payload_kg,
        min_flight_time_min=args.min_flight_time_min,
        max_time_constant_ms=args.max_time_constant_ms,
    )
    measured = _measured(args, catalog)
    rules = rules_from_args(args)
    prop_data = None
    if args.prop_data:
        build, info = prop_data_build(catalog)
        prop_data = {"build": build, "coefficients": info.pop("coefficients"), "report": info}
    if args.series is not None or args.parallel is not None:
        result = solve_packs(args, catalog, objective, requirements, measured, rules, prop_data)
    else:
        result = solve(catalog, objective, tuple(args.actuators), requirements, args.method,
                       measured, rules, prop_data)
    if args.max_roll_rise_ms is not None:
        if rules is not None or prop_data is not None or args.series is not None:
            raise RequestError("--max-roll-rise-ms does not combine with --flyable, --prop-data "
                               "or --series/--parallel yet (the flown candidates come from the "
                               "plain catalog model)")
        result = _fly_filter(args, catalog, objective, requirements, result, measured)
    if args.json:
        doc = result.to_dict()
        if measured is not None:
            doc["measured"] = measured.describe()
        if rules is not None:
            doc["rules"] = {"enabled": list(rules.enabled), "removed": result.rule_reports}
        if prop_data is not None:
            doc["propeller_data"] = prop_data["report"]
        print(json.dumps(doc, indent=2, default=_json_default))
    else:
        print_table(result)
        for d in result.designs:
            info = d.extra.get("flight")
            if info and d.feasible:
                print(f"{d.actuators} actuators: roll rise {info['roll_rise_ms']:.0f} ms <= "
                      f"{info['max_roll_rise_ms']:g} ms (flew {info['flown']} design(s))")
        if prop_data is not None:
            rep = prop_data["report"]
            print(f"propeller data (APC static): {len(rep['matched'])} matched, missed: "
                  f"{', '.join(rep['missed']) or 'none'}")
        if rules is not None:
            print_rule_reports(result.rule_reports)
    return 0 if result.any_feasible else EXIT_NO_FEASIBLE


def _fly_filter(args: argparse.Namespace, catalog: Any, objective: Objective,
                requirements: Any, result: Any, measured: Any) -> Any:
    """--max-roll-rise-ms: fly the MILP's picks, then candidates (optimizer.flight.choice)."""
    from optimizer.flight.choice import meet_roll_rise

    if args.method == "thesis":
        raise RequestError("--max-roll-rise-ms works with --method milp or exact")
    result = meet_roll_rise(result, catalog, objective, requirements, args.max_roll_rise_ms,
                            build_grid=None if measured is None else measured.build_grid)
    if measured is not None:
        measured.annotate(result)
    return result


def solve_packs(args: argparse.Namespace, catalog: Any, objective: Objective,
                requirements: Any, measured: Any, rules: Any, prop_data: Any) -> Any:
    """``--series/--parallel``: ``optimizer.packs.optimize_packs`` with the same options."""
    from optimizer.packs import optimize_packs, parse_counts

    if args.series is None:
        raise RequestError("--parallel needs --series (e.g. --series 2-6 --parallel 1-4)")
    if measured is not None:
        raise RequestError("--series/--parallel do not combine with --measured (measured "
                           "currents belong to the bench's supply voltage)")
    series = parse_counts(args.series, "--series")
    parallel = parse_counts(args.parallel or "1", "--parallel")
    build, coefficients = None, None
    if prop_data is not None:
        build, coefficients = prop_data["build"], prop_data["coefficients"]
    builder = None
    if rules is not None:
        from optimizer.flyable import FlyableBuilder

        build = builder = FlyableBuilder(rules, build, coefficients=coefficients)
    result = optimize_packs(catalog, objective, tuple(args.actuators), requirements,
                            args.method, series, parallel, build_grid=build)
    if builder is not None:
        result.rule_reports = _sum_reports(builder.reports)
    return result


def _sum_reports(reports: list[Any]) -> list[dict[str, Any]]:
    """Rule reports of the per-S grids added up per actuator count."""
    out: dict[int, dict[str, Any]] = {}
    for r in reports:
        d = r.to_dict()
        zero = {key: 0 for key in ("designs", "physically_feasible", "flyable")}
        acc = out.setdefault(d["actuators"], {
            **d, **zero,
            "removed_alone": dict.fromkeys(d["removed_alone"], 0),
            "removed_in_turn": dict.fromkeys(d["removed_in_turn"], 0),
        })
        for key in ("designs", "physically_feasible", "flyable"):
            acc[key] += d[key]
        for key in ("removed_alone", "removed_in_turn"):
            for name, v in d[key].items():
                acc[key][name] += v
    return list(out.values())


def print_rule_reports(reports: list[dict[str, Any]]) -> None:
    """One line per actuator count: designs each rule removed (alone / in turn)."""
    for r in reports:
        parts = ", ".join(f"{k} {r['removed_alone'][k]}/{r['removed_in_turn'][k]}"
                          for k in r["removed_alone"])
        print(f"rules, {r['actuators']} actuators: {r['physically_feasible']} of "
              f"{r['designs']} designs within the limits, {r['flyable']} flyable; removed "
              f"(alone/in turn): {parts}")


def _json_default(obj: Any) -> Any:
    if hasattr(obj, "item"):
        return obj.item()
    if isinstance(obj, tuple | set):
        return list(obj)
    raise TypeError(f"not JSON serialisable: {type(obj).__name__}")


def _fmt(value: Any, fmt: str) -> str:
    if value is None:
        return "-"
    if fmt == "s":
        return str(value)
    if isinstance(value, float) and not math.isfinite(value):
        return "-"
    return format(value, fmt)


def print_table(result: Any, title: str | None = None, console: Any = None) -> None:
    """Rich table like Table E.8: one column per actuator count, best marked."""
    from rich.console import Console
    from rich.table import Table

    console = console or Console(soft_wrap=False)
    req = result.requirements
    bits = [f"objective {result.objective.name}", f"payload {req.payload_kg:g} kg"]
    if req.min_flight_time_min is not None:
        bits.append(f"flight time >= {req.min_flight_time_min:g} min")
    if req.max_time_constant_ms is not None:
        bits.append(f"time constant <= {req.max_time_constant_ms:g} ms")
    bits.append(f"method {result.method}")
    table = Table(title=title or ", ".join(bits), title_justify="left")
    table.add_column("Number of actuators", style="bold", no_wrap=True)
    best = result.best
    for d in result.designs:
        mark = " * best" if best is not None and d is best else ""
        table.add_column(f"{d.actuators}{mark}", justify="right", max_width=48)
    any_measured = False
    for label, key, fmt in ROWS:
        cells = []
        for d in result.designs:
            if not d.feasible:
                cells.append("infeasible" if key == "propeller" else "-")
            else:
                value = getattr(d, key) if fmt == "s" else d.metrics.get(key)
                cell = _fmt(value, fmt)
                if is_measured(d.extra.get("sources"), key):
                    cell, any_measured = f"{cell} {MEASURED_MARK}", True
                cells.append(cell)
        table.add_row(label, *cells)
    table.add_row("Solve time (s)", *(f"{d.solve_time_s:.4f}" for d in result.designs))
    table.add_row("Status", *(_status(d) for d in result.designs))
    if any(not d.feasible for d in result.designs):
        table.add_row("Reason", *(d.reason or "" for d in result.designs))
    console.print(table)
    if best is None:
        console.print("No feasible design for any actuator count.", style="bold red")
    else:
        console.print(
            f"Best: {best.actuators} actuators, propeller {best.propeller}, motor "
            f"{best.motor}, battery {best.battery}"
        )
    if any_measured:
        console.print(f"{MEASURED_MARK} measured on the bench (runs in --json 'sources'); "
                      "other numbers from the datasheet model", style="dim")
    if result.source:
        console.print(f"Catalog: {result.source}", style="dim")


def _status(d: Any) -> str:
    status = d.status
    if d.mip_gap is not None:
        status += f" (gap {d.mip_gap:.0%})"
    if d.n_tied > 1:
        status += f", {d.n_tied} tied"
    return status
