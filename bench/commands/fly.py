"""``rotorbench fly``: fly a design through Paper B's maneuvers, or rank a whole catalog.

One design (``--actuators --propeller --motor --battery``): hover and the maneuvers
(roll_step, pitch_step, yaw_step, altitude_step, gust by default) on the flight model of
``optimizer.flight`` with gains from its rule; the actuators are the catalog model's, the
measured store's (``--measured DIR``, as ``optimize``) or a step run fitted now
(``--step-run RUN``). ``--sweep`` flies every feasible design of the catalog for one
actuator count through ``roll_step`` and reports how well the time constant ranks the
closed-loop roll rise time (Spearman rho, a table, with ``--plot`` a scatter PNG); feasible
includes the hover margin of ``--min-thrust-to-weight`` (default 1.2; ``--thesis-rules``
flies the thesis' feasible set, designs that cannot hover included and left out of rho).
Exit 0, 2 for bad input.
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path
from typing import Any

from bench.cli_support import (
    add_catalog_args,
    add_hover_args,
    add_measured_args,
    add_store_args,
    check_writable,
    hover_margin_from_args,
    json_default,
    measured_from_args,
    run_folder_arg,
)
from bench.store.catalogs import load
from optimizer.errors import RequestError


def register(subparsers: argparse._SubParsersAction) -> None:
    from optimizer.flight.maneuvers import MANEUVERS
    from optimizer.flight.vehicle import LAYOUTS

    p = subparsers.add_parser(
        "fly", help="fly a design (Paper B model, mixer, cascade controller) or rank a catalog",
        description="Fly one design of a catalog through hover and step maneuvers with "
        "gains from the vehicle and actuator model, or (--sweep) fly every feasible design "
        "and rank the time constant against the closed-loop roll rise time.")
    add_catalog_args(p)
    p.add_argument("--actuators", type=int, default=None, metavar="N",
                   help="actuator count: 4, 6 or 8 (--sweep: default 4)")
    p.add_argument("--propeller", metavar="ID")
    p.add_argument("--motor", metavar="ID")
    p.add_argument("--battery", metavar="ID")
    p.add_argument("--layout", choices=LAYOUTS, default="x", help="frame layout (default x)")
    p.add_argument("--maneuver", nargs="+", choices=tuple(MANEUVERS), default=None,
                   metavar="NAME", help=f"maneuvers to fly (default all: {', '.join(MANEUVERS)})")
    p.add_argument("--drag", type=float, default=0.0, metavar="N_S_M",
                   help="linear air drag coefficient, N per m/s (default 0)")
    add_measured_args(p)
    add_store_args(p)
    p.add_argument("--step-run", type=Path, default=None, metavar="RUN",
                   help="fit this step run now and fly with its rising/falling time "
                   "constants, latency and ESC frame")
    p.add_argument("--plot", type=Path, default=None, metavar="DIR",
                   help="write PNG figures (one per maneuver; --sweep: the ranking scatter)")
    p.add_argument("--sweep", action="store_true",
                   help="fly every feasible design (roll_step) and rank time constant vs "
                   "roll rise time")
    add_hover_args(p)
    p.set_defaults(func=handler)


def step_constants(run: Path) -> Any:
    """Fit a step run (as ``rotorbench constants`` does) into flight-model numbers."""
    from analysis.run_record import esc_frame_s, read_run
    from bench.store.constants_fit import fit_for_store
    from optimizer.flight.design import StepConstants

    key, kind, run_id, data = fit_for_store(run)
    if kind != "step":
        raise RequestError(f"--step-run {run}: a {kind} run; give a step run (kind step1)")
    return StepConstants(
        data["tau_up_s"], data["tau_down_s"], max(0.0, data["latency_s"]),
        esc_frame_s(read_run(run)),
        f"step run {run_id} ({key.motor} / {key.propeller}, {key.esc_mode})",
        motor=key.motor, propeller=key.propeller)


def step_run_mismatch(step: Any, propeller: str, motor: str) -> str | None:
    """A step run of another actuator flies this design's rotors with that actuator's
    response: allowed (what if), but said, naming both."""
    if step is None:
        return None
    other = [f"{what} {got} (design: {want})"
             for what, got, want in (("motor", step.motor, motor),
                                     ("propeller", step.propeller, propeller))
             if got is not None and got != want]
    if not other:
        return None
    return (f"--step-run measured another actuator: {', '.join(other)}; its time constants "
            "are flown on this design's rotors")


def _grid(args: argparse.Namespace, catalog: Any, n: int) -> Any:
    from optimizer.design_model import evaluate_grid

    measured = measured_from_args(args, catalog)
    if measured is not None:
        return measured.build_grid(catalog, n, args.payload_kg), measured
    return evaluate_grid(catalog, n, args.payload_kg), None


def _check_args(args: argparse.Namespace) -> int:
    from optimizer.flight.vehicle import FLIGHT_ACTUATORS

    n = args.actuators if args.actuators is not None else (4 if args.sweep else None)
    if n is None:
        raise RequestError("--actuators: give the actuator count (4, 6 or 8)")
    if n not in FLIGHT_ACTUATORS:
        raise RequestError(f"--actuators: the flight model flies 4, 6 or 8, got {n}")
    if not (math.isfinite(args.drag) and args.drag >= 0):
        raise RequestError(f"--drag: expected a coefficient >= 0 N s/m, got {args.drag}")
    if args.sweep:
        for name in ("propeller", "motor", "battery", "maneuver"):
            if getattr(args, name) is not None:
                raise RequestError(f"--{name} does not apply to --sweep (it flies every "
                                   "feasible design through roll_step)")
    else:
        missing = [f"--{k}" for k in ("propeller", "motor", "battery") if not getattr(args, k)]
        if missing:
            raise RequestError(f"{', '.join(missing)}: name the design to fly (or --sweep)")
    return n


def handler(args: argparse.Namespace) -> int:
    n = _check_args(args)
    if args.plot is not None:  # refuse before flying, not after (nothing half-written)
        check_writable(args.plot, "--plot", folder=True)
    margin = hover_margin_from_args(args)
    catalog = margin.apply(load(args.catalog, args.current_model))
    step = (step_constants(run_folder_arg(args, args.step_run))
            if args.step_run is not None else None)
    grid, measured = _grid(args, catalog, n)
    if args.sweep:
        return _sweep(args, catalog, grid, step, measured, margin)
    return _one(args, catalog, grid, step, measured)


def _one(args: argparse.Namespace, catalog: Any, grid: Any, step: Any, measured: Any) -> int:
    from optimizer.design_model import design_record
    from optimizer.flight.design import design_index, fly_report, setup
    from optimizer.flight.maneuvers import MANEUVERS, maneuver

    index = design_index(grid, args.propeller, args.motor, args.battery)
    record = design_record(grid, *index)
    vehicle, actuator = setup(catalog, grid, index, layout=args.layout, step=step,
                              drag_n_s_m=args.drag)
    names = args.maneuver or list(MANEUVERS)
    report, flights = fly_report(vehicle, actuator, [maneuver(m) for m in names], record,
                                 keep=args.plot is not None)
    report["catalog"] = catalog.source
    mismatch = step_run_mismatch(step, args.propeller, args.motor)
    report["warnings"] = [mismatch] if mismatch else []
    if measured is not None:
        report["measured_store"] = measured.describe()
    if args.plot is not None:
        from bench.figures.fly_figures import maneuver_figures

        report["plots"] = [str(p) for p in maneuver_figures(flights, vehicle, args.plot)]
    if args.json:
        print(json.dumps(report, indent=2, default=json_default))
        return 0
    _print_one(report)
    for line in report["warnings"]:
        print(f"warning: {line}")
    return 0


def _fmt(x: Any, spec: str = ".0f") -> str:
    return "-" if x is None else format(x, spec)


def _print_one(report: dict[str, Any]) -> None:
    from rich.console import Console
    from rich.table import Table

    d, h, a = report["design"], report["hover"], report["actuator"]
    console = Console(soft_wrap=False)
    title = (f"{d['actuators']} x {d['propeller']} + {d['motor']} + {d['battery']} "
             f"({report['vehicle']['layout']}), actuator tau up {a['tau_up_ms']:.1f} / down "
             f"{a['tau_down_ms']:.1f} ms, latency {a['latency_ms']:.1f} ms ({a['source']})")
    table = Table(title=title, title_justify="left")
    for col in ("maneuver", "rise 10-90 % (ms)", "overshoot (%)", "settling 2 % (ms)",
                "saturation (%)"):
        table.add_column(col, justify="right" if col != "maneuver" else "left")
    for name, m in report["maneuvers"].items():
        table.add_row(name, _fmt(m["rise_time_ms"]), _fmt(m["overshoot_pct"], ".1f"),
                      _fmt(m["settling_time_ms"]), _fmt(m["saturation_pct"], ".1f"))
    console.print(table)
    console.print(f"hover: {h['rpm']:.0f} rpm (evaluate: {_fmt(h['evaluate_hover_rpm'])} rpm), "
                  f"throttle {h['throttle']:.2f}, power {_fmt(h['power_w'], '.1f')} W "
                  f"(shaft power {_fmt(h['shaft_power_w'], '.1f')} W at the trim)")
    if not h["can_hover"]:
        console.print(f"{h['note']}: the maneuvers above are a fall, not a flight",
                      style="red")
    g = report["gains"]
    console.print(f"gains: rate crossover {g['rate_crossover_rad_s']:.1f} rad/s, attitude "
                  f"crossover {g['attitude_crossover_rad_s']:.1f} rad/s (phase margins "
                  f"{g['phase_margins_deg']['rate']:.0f} / "
                  f"{g['phase_margins_deg']['attitude']:.0f} deg)", style="dim")
    if not d.get("feasible", True):
        console.print(f"design is infeasible in the optimizer: {d.get('reason')}", style="red")
    for p in report.get("plots", []):
        console.print(f"wrote {p}", style="dim")


def _sweep(args: argparse.Namespace, catalog: Any, grid: Any, step: Any, measured: Any,
           margin: Any) -> int:
    from rich.console import Console
    from rich.progress import Progress

    from optimizer.flight.ranking import rank

    with Progress(console=Console(stderr=True), transient=True) as bar:
        task = bar.add_task(f"flying {grid.n_actuators}-rotor designs", total=None)
        ranking = rank(catalog, grid, lambda i, total: bar.update(task, completed=i,
                                                                  total=total),
                       layout=args.layout, step=step, drag_n_s_m=args.drag)
    doc = ranking.to_dict()
    doc["catalog"] = catalog.source
    doc["hover_margin"] = margin.to_dict(catalog)
    if measured is not None:
        doc["measured_store"] = measured.describe()
    if args.plot is not None:
        from bench.figures.fly_figures import ranking_scatter

        doc["plots"] = [str(ranking_scatter(ranking, args.plot, Path(catalog.source).name))]
    if args.json:
        print(json.dumps(doc, indent=2, default=json_default))
        return 0
    print_ranking(ranking, Console(soft_wrap=False))
    print(margin.describe(catalog))
    for p in doc.get("plots", []):
        print(f"wrote {p}")
    return 0


def print_ranking(ranking: Any, console: Any) -> None:
    """The ranking table: designs by time constant, their roll step, Spearman rho."""
    from rich.table import Table

    rows = sorted(ranking.rows, key=lambda r: r.time_constant_ms)
    table = Table(title=f"{ranking.actuators} actuators: time constant vs closed-loop roll "
                  "rise time (10 deg step)", title_justify="left")
    for col in ("design", "tau (ms)", "rise 10-90 % (ms)", "overshoot (%)", "saturation (%)",
                "note"):
        table.add_column(col, justify="left" if col in ("design", "note") else "right")
    for r in rows:
        table.add_row(f"{r.propeller}+{r.motor}+{r.battery}", f"{r.time_constant_ms:.1f}",
                      _fmt(r.rise_time_ms), f"{r.overshoot_pct:.1f}",
                      f"{r.saturation_pct:.1f}", r.note)
    console.print(table)
    rho = "-" if math.isnan(ranking.rho) else f"{ranking.rho:.3f}"
    console.print(f"Spearman rho (time constant vs roll rise time, {ranking.n_ranked} designs "
                  f"that hover): {rho}; flown in {ranking.seconds:.1f} s")
