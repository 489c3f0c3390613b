"""``rotorbench step``: Paper C's thrust steps (Step 1 or Step 2) on a rig."""

from __future__ import annotations

import argparse
import sys

from bench.cli_args.option_values import refuse_unused
from bench.cli_args.run_args import (
    add_common_arguments,
    dry_run_text,
    load_rig_from_args,
    parse_limits,
    run_options_from_args,
)
from bench.cli_args.store_args import publish_runs, recording_store
from bench.plans.plan_specs import named_step_sequence
from bench.plans.sequences import Sequence


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "step", help="run Paper C thrust steps (Step 1 / Step 2) and record them",
        description="Thrust steps between hover -30 % and +30 % (175 g and 325 g per rotor "
                    "of the 1 kg quadcopter, Paper C section 4). Setpoints become ESC "
                    "commands through the rig's static thrust map; if the rig has none yet, "
                    "a sweep measures it first and stores it with the rig (for a shipped or "
                    "read-only rig: in a copy under OUT/rigs/, used by later runs with the "
                    "same --out).")
    add_common_arguments(p)
    p.add_argument("--sequence", default="step1", metavar="step1|step2|FILE",
                   help="Paper C Step 1 (default) or Step 2, or a sequence file (.json/.toml "
                        "with name, limits and steps, as stored in run.json)")
    p.add_argument("--repeats", type=int, default=20, help="number of up/down steps (20)")
    p.add_argument("--hold", type=float, default=0.5, help="seconds each level is held (0.5)")
    p.set_defaults(func=handler)


def build(args: argparse.Namespace) -> Sequence:
    if args.sequence not in ("step1", "step2"):  # a file's steps carry their own holds
        refuse_unused(args, ("--repeats", "--hold"),
                          f"with --sequence {args.sequence} (a sequence file's steps set "
                          "their own repeats and holds)")
    return named_step_sequence(args.sequence, args.repeats, args.hold,
                               parse_limits(args.limit))


def handler(args: argparse.Namespace) -> int:
    from bench.jobs.map_sweep import measure_map
    from bench.jobs.run_progress import (
        JobOutput,
        check_budget_of,
        check_limits,
        err_console,
        report,
        run_with_progress,
    )

    output = JobOutput(out=print, err=_to_stderr)
    store = recording_store(args, warn=_to_stderr)  # before the rig: a lab store spools
    rig = load_rig_from_args(args, prefer_out_copy=True, tell=print)
    seq = build(args)
    check_limits(rig, seq)  # before a sweep for a missing map could start
    options = run_options_from_args(args)  # a bad --tick: the dry run says so too
    if args.dry_run:
        no_map = rig.thrust_map is None and seq.needs_thrust_map
        print(dry_run_text(rig, seq, note=(
            "no static thrust map in the rig yet: a sweep would run first (`rotorbench sweep "
            "--dry-run` shows it); thrust-step commands shown as (map)") if no_map else None))
        return 0
    check_budget_of(rig, seq, args.yes)  # before a sweep for a missing map could start
    if rig.thrust_map is None and seq.needs_thrust_map:
        err_console().print(
            f"rig {rig.name} has no static thrust map yet: measuring one with a sweep first")
        rig, code = measure_map(rig, args.out, limits=parse_limits(args.limit),
                                seed=args.seed, options=options, live=args.live,
                                confirmed=args.yes, output=output)
        if code:
            publish_runs(store, tell=print)
            return code
    outcome = run_with_progress(rig, seq, args.out, seed=args.seed, options=options,
                                live=args.live, confirmed=args.yes, output=output)
    code = report(outcome, output)
    publish_runs(store, outcome.run_dir, tell=print)
    return code


def _to_stderr(line: str) -> None:
    print(line, file=sys.stderr, flush=True)
