"""``rotorbench step``: Paper C's thrust steps (Step 1 or Step 2) on a rig."""

from __future__ import annotations

import argparse

from bench import cli_support as cli
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
    cli.add_common_arguments(p)
    p.add_argument("--sequence", default="step1", metavar="step1|step2|FILE",
                   help="Paper C Step 1 (default) or Step 2, or a sequence file (.json/.toml "
                        "with name, limits and steps, as stored in run.json)")
    p.add_argument("--repeats", type=int, default=20, help="number of up/down steps (20)")
    p.add_argument("--hold", type=float, default=0.5, help="seconds each level is held (0.5)")
    p.set_defaults(func=handler)


def build(args: argparse.Namespace) -> Sequence:
    if args.sequence not in ("step1", "step2"):  # a file's steps carry their own holds
        cli.refuse_unused(args, ("--repeats", "--hold"),
                          f"with --sequence {args.sequence} (a sequence file's steps set "
                          "their own repeats and holds)")
    return named_step_sequence(args.sequence, args.repeats, args.hold,
                               cli.parse_limits(args.limit))


def handler(args: argparse.Namespace) -> int:
    from bench.jobs.map_sweep import measure_map
    from bench.jobs.run_progress import (
        check_budget_of,
        check_limits,
        err_console,
        report,
        run_with_progress,
    )

    store = cli.recording_store(args)  # before the rig: a lab store records into the spool
    rig = cli.load_rig_from_args(args, prefer_out_copy=True)
    seq = build(args)
    check_limits(rig, seq)  # before a sweep for a missing map could start
    options = cli.run_options_from_args(args)  # a bad --tick: the dry run says so too
    if args.dry_run:
        no_map = rig.thrust_map is None and seq.needs_thrust_map
        cli.print_dry_run(rig, seq, note=(
            "no static thrust map in the rig yet: a sweep would run first (`rotorbench sweep "
            "--dry-run` shows it); thrust-step commands shown as (map)") if no_map else None)
        return 0
    check_budget_of(rig, seq, args.yes)  # before a sweep for a missing map could start
    if rig.thrust_map is None and seq.needs_thrust_map:
        err_console().print(
            f"rig {rig.name} has no static thrust map yet: measuring one with a sweep first")
        rig, code = measure_map(rig, args.out, limits=cli.parse_limits(args.limit),
                                seed=args.seed, options=options, live=args.live,
                                confirmed=args.yes)
        if code:
            cli.publish_runs(store)
            return code
    outcome = run_with_progress(rig, seq, args.out, seed=args.seed, options=options,
                                live=args.live, confirmed=args.yes)
    code = report(outcome)
    cli.publish_runs(store, outcome.run_dir)
    return code
