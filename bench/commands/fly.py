"""``rotorbench fly``: fly a design through Paper B's maneuvers, or a whole catalog.

One design (``--actuators --propeller --motor --battery``): hover and the maneuvers
(roll_step, pitch_step, yaw_step, altitude_step, gust by default) on the flight model of
``optimizer.flight`` with gains from its rule; the actuators are the catalog model's, the
measured store's (``--measured DIR``, as ``optimize``) or a step run fitted now
(``--step-run RUN``).

``--sweep`` flies every design ``optimize`` would consider with the same options (payload,
hover margin: ``--min-thrust-to-weight``, default 1.2, or ``--thesis-rules``, which flies
designs that cannot hover too; ``--flyable`` and its rules; ``--measured``;
``--series``/``--parallel`` packs) with the sweep engine (``optimizer.sweep``,
``bench.jobs.sweep_run``): in this process, on a local Dask cluster (``--workers K``) or
on a running one (``--scheduler ADDRESS``). With ``--out SWEEP.parquet`` one row per
design and maneuver figures go to a Parquet file (an interrupted sweep resumes;
docs/sweeps.md); without it, one actuator count's designs fly ``roll_step`` and the
command reports how well the time constant ranks the closed-loop roll rise time
(Spearman rho, a table, with ``--plot`` a scatter PNG; designs that cannot hover are
left out of rho). Exit 0, 2 for bad input (another sweep writing the same ``--out``,
``--samples`` beyond the memory, a ``--scheduler`` that is no Dask scheduler) or an
output folder that stops taking writes (the finished chunks are kept), 1 when the
cluster was lost (likewise), 130 on Ctrl-C (likewise).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import sys
from pathlib import Path
from typing import Any

from bench.cli_args.option_values import refuse_unused
from bench.cli_args.sizing_args import (
    RULE_FLAGS,
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
from bench.cli_args.store_args import add_store_args, run_folder_arg
from bench.paths.outputs import check_writable
from bench.store.catalogs import load
from optimizer.errors import RequestError


def register(subparsers: argparse._SubParsersAction) -> None:
    from optimizer.flight.maneuvers import MANEUVERS
    from optimizer.flight.vehicle import LAYOUTS

    p = subparsers.add_parser(
        "fly", help="fly a design (Paper B model, mixer, cascade controller) or a catalog",
        description="Fly one design of a catalog through hover and step maneuvers with "
        "gains from the vehicle and actuator model, or (--sweep) fly every design optimize "
        "would consider: into a Parquet file (--out), or ranking the time constant against "
        "the closed-loop roll rise time.")
    add_catalog_args(p)
    p.add_argument("--actuators", type=int, nargs="+", default=None, metavar="N",
                   help="actuator count: 4, 6 or 8 (--sweep --out: one or more; --sweep: "
                   "default 4)")
    p.add_argument("--propeller", metavar="ID")
    p.add_argument("--motor", metavar="ID")
    p.add_argument("--battery", metavar="ID")
    p.add_argument("--layout", choices=LAYOUTS, default="x", help="frame layout (default x)")
    p.add_argument("--maneuver", nargs="*", choices=tuple(MANEUVERS), default=None,
                   metavar="NAME", help=f"maneuvers to fly (default all: {', '.join(MANEUVERS)}; "
                   "--controller betaflight: none named, only the rate steps)")
    p.add_argument("--drag", type=float, default=0.0, metavar="N_S_M",
                   help="linear air drag coefficient, N per m/s (default 0)")
    add_measured_args(p)
    add_store_args(p)
    p.add_argument("--step-run", type=Path, default=None, metavar="RUN",
                   help="fit this step run now and fly with its rising/falling time "
                   "constants, latency and ESC frame")
    p.add_argument("--plot", type=Path, default=None, metavar="DIR",
                   help="write PNG figures (one per maneuver; --sweep: the ranking scatter)")
    b = p.add_argument_group("Betaflight in the loop (docs/flight.md)")
    b.add_argument("--controller", choices=("cascade", "betaflight"), default="cascade",
                   help="cascade: the thesis' controller (default); betaflight: Betaflight "
                   "4.6.0's firmware (its SITL, extra sitl) flies the design in real time, "
                   "the cascade's figures beside it")
    b.add_argument("--betaflight-cli", type=Path, default=None, metavar="FILE",
                   help="Betaflight CLI lines (PIDs, rates, filters, motor_idle; diff "
                   "output works) applied and saved before the flight")
    b.add_argument("--rate-steps", type=float, default=6.0, metavar="S",
                   help="betaflight: seconds of roll/pitch rate steps (acro) after the "
                   "maneuvers, for the log's step response (default 6, 0: none)")
    p.add_argument("--sweep", action="store_true",
                   help="fly every design optimize would consider: with --out into a Parquet "
                   "file, else through roll_step, ranking time constant vs roll rise time")
    add_hover_args(p)
    add_rule_args(p)
    g = p.add_argument_group("sweep (docs/sweeps.md)")
    add_pack_args(g)
    g.add_argument("--out", type=Path, default=None, metavar="SWEEP.parquet",
                   help="write one row per design (keys, static numbers, maneuver figures); "
                   "an interrupted sweep resumes from SWEEP.parquet.parts/")
    g.add_argument("--workers", type=int, default=1, metavar="K",
                   help="worker processes of a local Dask cluster (default 1: this process)")
    g.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="fly on a running Dask cluster, e.g. tcp://host:8786")
    g.add_argument("--chunk-size", type=int, default=None, metavar="N",
                   help="designs per task and part (default: up to 1024, at least 4 chunks "
                   "per worker)")
    g.add_argument("--samples", type=int, default=1, metavar="M",
                   help="robust designs: fly each design M times with its time constants, "
                   "latency and rotor constants drawn from the measured spreads of "
                   "--measured; adds 5th/50th/95th percentile columns (default 1: nominal)")
    g.add_argument("--seed", type=int, default=0, metavar="S",
                   help="with --samples: the seed hashed with each design's keys (default 0)")
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
    from optimizer.model.design_model import evaluate_grid

    measured = measured_from_args(args, catalog)
    if measured is not None:
        return measured.build_grid(catalog, n, args.payload_kg), measured
    return evaluate_grid(catalog, n, args.payload_kg), None


#: options of --sweep only
SWEEP_FLAGS = ("--out", "--workers", "--scheduler", "--chunk-size", "--flyable", *RULE_FLAGS,
               "--series", "--parallel", "--samples", "--seed")


def _check_args(args: argparse.Namespace) -> list[int]:
    from optimizer.flight.vehicle import FLIGHT_ACTUATORS

    counts = args.actuators or ([4] if args.sweep else [])
    if not counts:
        raise RequestError("--actuators: give the actuator count (4, 6 or 8)")
    for n in counts:
        if n not in FLIGHT_ACTUATORS:
            raise RequestError(f"--actuators: the flight model flies 4, 6 or 8, got {n}")
    if not (math.isfinite(args.drag) and args.drag >= 0):
        raise RequestError(f"--drag: expected a coefficient >= 0 N s/m, got {args.drag}")
    if not args.sweep:
        refuse_unused(args, SWEEP_FLAGS, "without --sweep")
        missing = [f"--{k}" for k in ("propeller", "motor", "battery") if not getattr(args, k)]
        if missing:
            raise RequestError(f"{', '.join(missing)}: name the design to fly (or --sweep)")
        if len(counts) > 1:
            raise RequestError("--actuators: one count names one design (--sweep flies several)")
        return counts
    for name in ("propeller", "motor", "battery"):
        if getattr(args, name) is not None:
            raise RequestError(f"--{name} does not apply to --sweep (it flies every "
                               "feasible design)")
    if args.out is None:
        if args.maneuver is not None:
            raise RequestError("--maneuver applies to --sweep --out (the ranking flies "
                               "roll_step)")
        if len(counts) > 1:
            raise RequestError("--actuators: the ranking (--sweep without --out) takes one "
                               "count; give --out SWEEP.parquet to fly several")
        if args.samples != 1 or args.seed != 0:
            raise RequestError("--samples and --seed apply to --sweep --out (the percentiles "
                               "go to its file)")
    else:
        if args.plot is not None:
            raise RequestError("--plot draws the ranking of --sweep without --out")
        if args.samples < 1:
            raise RequestError(f"--samples: expected a number of flights per design >= 1, "
                               f"got {args.samples}")
        if args.seed < 0:
            raise RequestError(f"--seed: expected a whole number >= 0, got {args.seed}")
        if args.out.suffix != ".parquet":
            raise RequestError(f"--out {args.out}: expected a file name ending in .parquet")
        check_writable(args.out, "--out", folder=False, make_parents=False)
    return counts


#: options of --controller betaflight only
BETAFLIGHT_FLAGS = ("--betaflight-cli", "--rate-steps")


def handler(args: argparse.Namespace) -> int:
    if args.controller == "betaflight":
        return _betaflight(args)
    refuse_unused(args, BETAFLIGHT_FLAGS, "without --controller betaflight")
    if args.maneuver == []:
        raise RequestError("--maneuver: name one or more maneuvers (none named flies only "
                           "Betaflight's rate steps, with --controller betaflight)")
    counts = _check_args(args)
    if args.plot is not None:  # refuse before flying, not after (nothing half-written)
        check_writable(args.plot, "--plot", folder=True)
    margin = hover_margin_from_args(args)
    catalog = margin.apply(load(args.catalog, args.current_model))
    step = (step_constants(run_folder_arg(args, args.step_run))
            if args.step_run is not None else None)
    if args.sweep:
        return _sweep(args, catalog, counts, step, margin)
    grid, measured = _grid(args, catalog, counts[0])
    return _one(args, catalog, grid, step, measured)


def _one(args: argparse.Namespace, catalog: Any, grid: Any, step: Any, measured: Any) -> int:
    from optimizer.flight.design import design_index, fly_report, setup
    from optimizer.flight.maneuvers import MANEUVERS, maneuver
    from optimizer.model.design_model import design_record

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


def _sweep(args: argparse.Namespace, catalog: Any, counts: list[int], step: Any,
           margin: Any) -> int:
    """Plan every design, fly it with the sweep engine; write the rows (``--out``) or
    print the ranking."""
    from bench.jobs.sweep_run import Executor, run_sweep
    from optimizer.flight.maneuvers import MANEUVERS
    from optimizer.solve.selection_options import grid_builder, pack_grid_builder
    from optimizer.sweep.designs import Packs, plan_designs
    from optimizer.sweep.spec import sweep_spec

    executor = Executor(args.workers, args.scheduler).check()
    measured = measured_from_args(args, catalog)
    rules = rules_from_args(args)
    packs = packs_from_args(args)
    build, _ = (pack_grid_builder(measured, rules) if packs is not None
                else grid_builder(measured, rules))
    plan = plan_designs(catalog, counts, args.payload_kg, build,
                        Packs(*packs) if packs is not None else None,
                        layout=args.layout, step=step, drag_n_s_m=args.drag)
    maneuvers = (args.maneuver or list(MANEUVERS)) if args.out is not None else ["roll_step"]
    options = {
        "actuators": counts, "payload_kg": args.payload_kg,
        "current_model": catalog.constants.current_model,
        "hover_margin": margin.to_dict(catalog),
        "rules": None if rules is None else dataclasses.asdict(rules),
        "series": None if packs is None else list(packs[0]),
        "parallel": None if packs is None else list(packs[1]),
        "measured": None if measured is None else measured.describe(),
        "step_run": None if step is None else {
            k: (None if isinstance(v, float) and math.isnan(v) else v)
            for k, v in dataclasses.asdict(step).items()},
        "layout": args.layout, "drag_n_s_m": args.drag,
    }
    spec = sweep_spec(catalog, plan, maneuvers, options, args.samples, args.seed)
    if args.samples > 1 and not _any_spread(plan):
        print("warning: --samples: no design has a measured spread (--measured with fitted "
              "step runs and sweeps gives them), so every sample is the nominal design",
              file=sys.stderr)
    result = run_sweep(plan, maneuvers, spec, out=args.out, executor=executor,
                       chunk=args.chunk_size)
    if args.out is None:
        return _ranking(args, catalog, counts[0], result, packs is not None, measured, margin)
    doc = {"out": str(args.out), "designs": len(plan), "errors": result.errors,
           "resumed": result.resumed, "flown": result.flown, "seconds": result.seconds,
           "chunk_size": result.chunk_size, "spec": spec}
    if args.json:
        print(json.dumps(doc, indent=2, default=json_default))
        return 0
    errors = f", {result.errors} did not fly (see column error)" if result.errors else ""
    print(f"wrote {args.out}: {len(plan)} designs x {len(maneuvers)} maneuvers{errors}; "
          f"{result.flown} flown in {result.seconds:.1f} s"
          + (f", {result.resumed} resumed" if result.resumed else ""))
    print(margin.describe(catalog))
    return 0


def _any_spread(plan: Any) -> bool:
    """Whether some design of the plan has a measured spread to draw samples from."""
    from optimizer.sweep.flight_params import STD_PREFIX

    spread = plan[[c for c in plan.columns if c.startswith(STD_PREFIX)]].to_numpy(float)
    return bool((spread > 0).any())


def _ranking(args: argparse.Namespace, catalog: Any, n: int, result: Any, packs: bool,
             measured: Any, margin: Any) -> int:
    """The time constant ranking of a sweep's rows: table, Spearman rho, scatter."""
    from rich.console import Console

    from optimizer.sweep.ranking import ranking_from_rows

    ranking = ranking_from_rows(n, result.table.to_pylist(), result.seconds, packs)
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


def _betaflight(args: argparse.Namespace) -> int:
    """One design flown by Betaflight's firmware, the thesis cascade's figures beside it;
    the firmware's log stored as a run of kind flight (docs/flight.md)."""
    import tempfile

    from bench.cli_args.store_args import DEFAULT_OUT, named_store
    from bench.jobs.betaflight_flight import DT_S, fly_betaflight, read_cli_file
    from bench.jobs.betaflight_program import BETAFLIGHT_MANEUVERS, RATE_PERIOD_S
    from bench.store.store_url import parse_store
    from drivers.backends.betaflight_cli import unknown_settings
    from drivers.backends.betaflight_sitl import find_binary
    from optimizer.flight.design import design_index, fly_report, setup
    from optimizer.flight.maneuvers import maneuver
    from optimizer.flight.plant import ExternalPlant
    from optimizer.model.design_model import design_record

    if args.sweep:
        raise RequestError("--controller betaflight flies one design (not --sweep)")
    refuse_unused(args, SWEEP_FLAGS, "with --controller betaflight")
    if args.plot is not None:
        raise RequestError("--plot draws the cascade's flights; --controller betaflight "
                           "keeps the firmware's log as a run (rotorbench flight-report)")
    names: list[str] = (list(BETAFLIGHT_MANEUVERS) if args.maneuver is None
                        else args.maneuver)
    other = [m for m in names if m not in BETAFLIGHT_MANEUVERS]
    if other:
        raise RequestError(f"--maneuver {' '.join(other)}: Betaflight flies "
                           f"{', '.join(BETAFLIGHT_MANEUVERS)} as stick inputs (yaw is a rate "
                           "in ANGLE mode; it holds no height)")
    if not (math.isfinite(args.rate_steps) and 0 <= args.rate_steps <= 120):
        raise RequestError(f"--rate-steps: expected 0 to 120 s, got {args.rate_steps}")
    if not names and args.rate_steps < RATE_PERIOD_S:
        raise RequestError("--maneuver names none and --rate-steps flies no step: nothing "
                           "to fly")
    counts = _check_args(args)
    if counts != [4] or args.layout != "x":
        raise RequestError("--controller betaflight: Betaflight's QUADX flies --actuators 4 "
                           "--layout x")
    cli_lines = read_cli_file(args.betaflight_cli) if args.betaflight_cli else []
    store = named_store(args)
    url = parse_store(store) if store else None
    if url is not None and url.folder is None:
        raise RequestError(f"--store {store}: the firmware's log is stored in a folder store")
    root = url.folder if url is not None and url.folder is not None else DEFAULT_OUT
    check_writable(root, "--store", folder=True)
    # not installed, or a setting this build does not have: one line, before any launch
    unknown = unknown_settings(find_binary(), cli_lines)
    if unknown:
        where, name = unknown[0]
        raise RequestError(f"--betaflight-cli {where}: no setting {name!r} in Betaflight "
                           "4.6.0's SITL (a typo, or a setting of another build)")
    margin = hover_margin_from_args(args)
    catalog = margin.apply(load(args.catalog, args.current_model))
    step = (step_constants(run_folder_arg(args, args.step_run))
            if args.step_run is not None else None)
    grid, measured = _grid(args, catalog, 4)
    index = design_index(grid, args.propeller, args.motor, args.battery)
    record = design_record(grid, *index)
    vehicle, actuator = setup(catalog, grid, index, layout=args.layout, step=step,
                              drag_n_s_m=args.drag)
    cascade, _ = fly_report(vehicle, actuator, [maneuver(m) for m in names], record)
    plant = ExternalPlant(vehicle, actuator, DT_S)
    Path(root).mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix=".betaflight-", dir=root) as tmp:
        log = Path(tmp) / "LOG00001.BF"
        flown_by: dict[str, Any] = {"controller": "betaflight", "design": cascade["design"],
                                    "actuator": cascade["actuator"],
                                    "cli": [line for _, line in cli_lines]}
        flight = None
        try:
            flight = fly_betaflight(plant, names, cli_lines, rate_steps_s=args.rate_steps,
                                    log_to=log, on_phase=lambda text: print(
                                        f"betaflight: {text}", file=sys.stderr))
            flown_by["firmware"] = flight.firmware
        finally:  # an interrupted or failed flight keeps its log too
            run_dir = _keep_log(log, root, flown_by, flight)
    assert flight is not None  # it raised otherwise
    report = {
        "controller": "betaflight",
        "design": cascade["design"],
        "hover": flight.hover,
        "maneuvers": flight.maneuvers,
        "rate_steps": flight.rate_steps,
        "vehicle": cascade["vehicle"],
        "actuator": cascade["actuator"],
        "betaflight": {**flight.firmware, "realtime": flight.realtime,
                       "cli": [line for _, line in cli_lines]},
        "flight_run": None if run_dir is None else str(run_dir),
        **_log_report(run_dir),
        "cascade": {"maneuvers": cascade["maneuvers"], "hover": cascade["hover"],
                    "gains": cascade["gains"]},
        "catalog": catalog.source,
        "warnings": [w for w in [step_run_mismatch(step, args.propeller, args.motor)] if w],
    }
    if measured is not None:
        report["measured_store"] = measured.describe()
    if args.json:
        print(json.dumps(report, indent=2, default=json_default))
        return 0
    _print_betaflight(report)
    return 0


def _keep_log(log: Path, root: Path, flown_by: dict[str, Any], flight: Any) -> Path | None:
    """The firmware's log stored as a flight run, with the plant's rotor speeds as its
    eRPM (``bench.jobs.betaflight_erpm``); a cut-short flight's (``flight`` None) is kept
    where it can be and said on stderr, never hiding why the flight ended."""
    from bench.jobs.betaflight_erpm import add_plant_erpm
    from bench.store.imported_run import store_flight_log

    if not log.is_file():
        return None
    cut_short = flight is None
    augment = None if cut_short else (lambda f: add_plant_erpm(f, flight.trace))
    try:
        run_dir = store_flight_log(log, root, "betaflight-flight", {"flown_by": flown_by},
                                   augment)
    except Exception:
        if not cut_short:
            raise
        return None
    if cut_short:
        print(f"betaflight: the cut-short flight's firmware log is stored as flight run "
              f"{run_dir}", file=sys.stderr)
    return run_dir


def _log_report(run_dir: Path | None) -> dict[str, Any]:
    """What ``rotorbench flight-report`` reads in the stored log: the rate step response
    per axis (deconvolved: its H1 and PID-Analyzer's; and measured directly on the stick
    steps) and each motor's in-flight response from the (synthesized) eRPM."""
    import numpy as np

    from analysis.flight_report import flight_report
    from analysis.run_record import read_run
    from analysis.stick_steps import step_readings
    from bench.jobs.betaflight_program import RATE_STEP_DPS

    if run_dir is None:
        return {"log_step_response": None, "log_motor_response": None}
    rec = read_run(run_dir)
    rep = flight_report(rec)
    t = rec.column("t_s")
    out: dict[str, Any] = {}
    for axis in ("x", "y"):
        r = rep.responses.get(axis)
        steps = step_readings(t, rec.column(f"rate_sp_{axis}_rad_s"),
                              rec.column(f"gyro_{axis}_rad_s"),
                              min_step=math.radians(0.5 * RATE_STEP_DPS))
        rises = [r for r, _ in steps]
        out[axis] = {
            "h1": r.metrics if r is not None else {},
            "pid_analyzer": (r.metrics_pa or {}) if r is not None else {},
            "direct_rise_ms": float(np.median(rises)) * 1e3 if rises else None,
            "direct_rises_ms": [1e3 * r for r in rises],
            "direct_steps": len(rises),
            "direct_overshoot_pct": float(np.median([o for _, o in steps])) if steps else None,
            **({"why": r.why} if r is not None and r.why else {})}
    return {"log_step_response": out,
            "log_motor_response": {m: r.summary() for m, r in rep.motors.items()},
            "log_synthesized": rec.meta.get("flight", {}).get("synthesized")}


def _print_betaflight(report: dict[str, Any]) -> None:
    from rich.console import Console
    from rich.table import Table

    from bench.jobs.betaflight_flight import SILENT_S

    d, bf = report["design"], report["betaflight"]
    console = Console(soft_wrap=False)
    table = Table(title=f"{d['actuators']} x {d['propeller']} + {d['motor']} + {d['battery']}: "
                  f"Betaflight {bf.get('version', '?')} (SITL) vs the thesis cascade",
                  title_justify="left")
    for col in ("maneuver", "rise BF (ms)", "rise cascade (ms)", "overshoot BF (%)",
                "overshoot cascade (%)", "settling BF (ms)", "settling cascade (ms)"):
        table.add_column(col, justify="left" if col == "maneuver" else "right")
    for name, m in report["maneuvers"].items():
        c = report["cascade"]["maneuvers"].get(name, {})
        table.add_row(name, _fmt(m["rise_time_ms"]), _fmt(c.get("rise_time_ms")),
                      _fmt(m["overshoot_pct"], ".1f"), _fmt(c.get("overshoot_pct"), ".1f"),
                      _fmt(m["settling_time_ms"]), _fmt(c.get("settling_time_ms")))
    if report["maneuvers"]:
        console.print(table)
    h, ch = report["hover"], report["cascade"]["hover"]
    console.print(f"hover throttle: Betaflight {_fmt(h.get('throttle'), '.3f')} (motor "
                  f"{_fmt(h.get('motor_us'))} us), cascade {ch['throttle']:.3f}")
    rt = bf["realtime"]
    console.print(f"real-time factor {_fmt(rt['real_time_factor'], '.3f')} ({rt['sim_s']:.1f} s "
                  f"flown in {rt['wall_s']:.1f} s; plant waited {rt['waited_for_firmware_s']:.2f}"
                  f" s for the firmware in {rt['waits']} silences over "
                  f"{1e3 * SILENT_S:.0f} ms, the longest {1e3 * rt['longest_wait_s']:.0f} ms;"
                  f" {_fmt(rt['answered_pct'], '.0f')} % of FDM packets answered within the "
                  "tick)")
    console.print(f"PIDs scaled to the design: simplified_master_multiplier "
                  f"{report['betaflight'].get('simplified_master_multiplier')} %")
    for name, r in (report.get("rate_steps") or {}).items():
        console.print(f"rate steps {name} in the loop (plant's rate, median): rise "
                      f"{_fmt(r['rise_ms'], '.1f')} ms, overshoot "
                      f"{_fmt(r['overshoot_pct'], '.1f')} % ({r['steps']} steps)")
    for axis, r in (report["log_step_response"] or {}).items():
        console.print(f"log step response {axis}: rise {_fmt(r['h1'].get('rise_ms'), '.1f')} ms "
                      f"deconvolved (H1), {_fmt(r['direct_rise_ms'], '.1f')} ms direct "
                      f"({r['direct_steps']} stick steps)")
    motors = report["log_motor_response"] or {}
    if motors:
        a = report["actuator"]
        up = [m["tau_up_ms"] for m in motors.values()]
        down = [m["tau_down_ms"] for m in motors.values()]
        console.print(f"in-flight motor response (eRPM synthesized from the plant): tau up "
                      f"{min(up):.1f}-{max(up):.1f} ms, down {min(down):.1f}-{max(down):.1f} "
                      f"ms (the actuator flown: up {a['tau_up_ms']:.1f}, down "
                      f"{a['tau_down_ms']:.1f} ms)")
    if report["flight_run"]:
        console.print(f"firmware log stored as flight run {report['flight_run']} "
                      "(rotorbench flight-report RUN)")
    for line in report["warnings"]:
        console.print(f"warning: {line}")
