"""The bench commands' run arguments (``step``, ``sweep``, ``console``): the rig, the
limits, the loop options, and the dry-run listing.
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

from bench.cli_args.option_values import seed_arg
from bench.cli_args.store_args import DEFAULT_OUT, add_store_args
from bench.errors import RigError

__all__ = ["add_common_arguments", "dry_run_text", "load_rig_from_args", "parse_limits",
           "run_options_from_args"]


def add_common_arguments(p: argparse.ArgumentParser) -> None:
    from bench.engine.safety import LIMIT_FIELDS

    p.add_argument("--rig", type=Path, default=None,
                   help="rig file (TOML); default: the simulated rig bench/data/rigs/sim.toml")
    p.add_argument("--out", type=Path, default=DEFAULT_OUT,
                   help="output root for run folders and runs.sqlite (default: ./runs); with "
                        "a lab --store, the data location (s3://bucket/prefix or a shared "
                        "folder)")
    p.add_argument("--esc-mode", choices=("complementary", "diode", "stock"), default=None,
                   help="ESC switching scheme / firmware (overrides the rig file)")
    p.add_argument("--seed", type=seed_arg, default=None, help="seed of the simulated rig")
    p.add_argument("--limit", action="append", default=[], metavar="NAME=VALUE",
                   help=f"tighten a limit for this run ({', '.join(LIMIT_FIELDS)}); "
                        "loosening is refused")
    p.add_argument("--dry-run", action="store_true",
                   help="print every step with times and commands; touch no device")
    p.add_argument("--live", action="store_true",
                   help="show rolling plots in a window (pyqtgraph); implies --realtime")
    p.add_argument("--realtime", action="store_true",
                   help="pace a simulated rig to the wall clock")
    p.add_argument("--yes", action="store_true",
                   help="run a plan longer than 1 h or projected above 2 GB of samples "
                        "(refused without it; a plan longer than 24 h is always refused)")
    p.add_argument("--tick", type=float, default=0.02,
                   help="command/read period in seconds; limits are checked on every "
                        "sample, the reaction comes within one tick (default 0.02)")
    p.add_argument("--accept-uncalibrated", action="store_true",
                   help="run although the newest calibration of a cell failed its "
                        "acceptance limits (it is then not applied; run.json says so)")
    add_store_args(p, records=True)


def load_rig_from_args(args: argparse.Namespace, prefer_out_copy: bool = False,
                       tell: Callable[[str], None] | None = None) -> Any:
    """The rig of ``--rig`` (default: the sim rig), with ``--esc-mode`` applied.

    ``prefer_out_copy``: for a read-only rig (shipped, or not writable) use the copy an
    earlier sweep stored under ``<out>/rigs/`` with its measured map, if there is one, and
    say so through ``tell`` (the command's output).
    """
    from bench.rig.rig import default_rig_path, load_rig, map_goes_to_copy, rig_copy_path

    rig = load_rig(args.rig or default_rig_path())
    if prefer_out_copy and map_goes_to_copy(rig):
        copy = rig_copy_path(rig.path, args.out)
        if copy.is_file():
            if tell is not None:
                tell(f"rig file: {copy} (the copy of read-only {rig.path} that holds the "
                     "map a sweep measured)")
            rig = load_rig(copy)
    if args.esc_mode:
        rig = rig.with_esc_mode(args.esc_mode)
    return rig


def parse_limits(items: list[str]) -> dict[str, float]:
    """``--limit NAME=VALUE`` items as a dict (names of ``bench.engine.safety.LIMIT_FIELDS``)."""
    from bench.engine.safety import LIMIT_FIELDS

    out = {}
    for item in items:
        name, sep, value = item.partition("=")
        if not sep or name not in LIMIT_FIELDS:
            raise RigError(f"--limit {item!r}: expected NAME=VALUE with NAME one of "
                           f"{', '.join(LIMIT_FIELDS)}")
        try:
            out[name] = float(value)
        except ValueError:
            raise RigError(f"--limit {item!r}: {value!r} is not a number") from None
        if not math.isfinite(out[name]):
            raise RigError(f"--limit {item!r}: expected a finite number")
    return out


def run_options_from_args(args: argparse.Namespace) -> Any:
    """The loop settings of ``--tick``, ``--realtime`` and ``--live`` (which implies it)."""
    from bench.plan_runner.runner import RunOptions

    return RunOptions(tick_s=args.tick, realtime=bool(args.realtime or args.live),
                      accept_uncalibrated=bool(getattr(args, "accept_uncalibrated", False)))


def dry_run_text(rig: Any, seq: Any, note: str | None = None) -> str:
    """The dry run the command prints: ``note``, the rig's ESC, every step with times and
    commands, the projection."""
    from bench.engine.safety import effective_limits
    from bench.plan_runner.session import plan_for
    from bench.plans.run_budget import check_budget, project, row_rate_hz
    from bench.plans.sequences import format_plan

    effective_limits(rig.limits, seq.limits, source=f"sequence {seq.name!r}",
                     thrust_setpoints_n=seq.thrust_setpoints_n)
    plan = plan_for(rig, seq, dry_run=True)
    budget = project(plan.duration_s, row_rate_hz(rig))
    # a plan no run may carry out is refused before its (millions of) lines are printed;
    # one that needs --yes is shown, the projection says what it costs
    check_budget(budget, seq.where, yes=True)
    lines = [note] if note else []
    lines += [f"rig {rig.name} ({rig.path}); ESC {rig.esc.idle_us:g} us idle, "
              f"{rig.esc.min_us:g}-{rig.esc.max_us:g} us at {rig.esc.frame_rate_hz:g} Hz",
              format_plan(plan), budget.describe()]
    return "\n".join(lines)
