"""``rotorbench sweep``: slow ramp; fits and stores the static thrust map (Paper C 4.4)."""

from __future__ import annotations

import argparse
import sys

from bench.cli_args.run_args import (
    add_common_arguments,
    dry_run_text,
    load_rig_from_args,
    parse_limits,
    run_options_from_args,
)
from bench.cli_args.store_args import publish_runs, recording_store
from bench.plans.plan_specs import sweep_sequence
from bench.plans.sequences import Sequence


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "sweep", help="slow throttle ramp: thrust, current and speed against command",
        description="Ramps the ESC command slowly and records thrust, current and speed "
                    "(Fig. C.13, C.14). Fits the static command->thrust map and stores it "
                    "with the rig (unless --no-save-map), for the thrust steps. A shipped "
                    "(or read-only) rig is never rewritten: the rig is copied to "
                    "OUT/rigs/ with the map beside it, and step/sweep with the same --out "
                    "use that copy.")
    add_common_arguments(p)
    p.add_argument("--start-us", type=float, default=1100.0)
    p.add_argument("--end-us", type=float, default=1900.0)
    p.add_argument("--duration", type=float, default=20.0, help="ramp time in seconds (20)")
    p.add_argument("--no-save-map", action="store_true", help="do not store the fitted map")
    p.set_defaults(func=handler)


def build(args: argparse.Namespace) -> Sequence:
    return sweep_sequence(args.start_us, args.end_us, args.duration,
                          parse_limits(args.limit))


def handler(args: argparse.Namespace) -> int:
    from bench.jobs.map_sweep import measure_map
    from bench.jobs.run_progress import JobOutput

    store = recording_store(args, warn=_to_stderr)  # before the rig: a lab store spools
    rig = load_rig_from_args(args, prefer_out_copy=True, tell=print)
    options = run_options_from_args(args)  # a bad --tick: the dry run says so too
    if args.dry_run:
        print(dry_run_text(rig, build(args)))
        return 0
    _, code = measure_map(rig, args.out, start_us=args.start_us, end_us=args.end_us,
                          duration_s=args.duration, limits=parse_limits(args.limit),
                          save=not args.no_save_map, seed=args.seed,
                          options=options, live=args.live,
                          confirmed=args.yes, output=JobOutput(out=print, err=_to_stderr))
    publish_runs(store, tell=print)
    return code


def _to_stderr(line: str) -> None:
    print(line, file=sys.stderr, flush=True)
