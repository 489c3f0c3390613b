"""``rotorbench sweep``: slow ramp; fits and stores the static thrust map (Paper C 4.4)."""

from __future__ import annotations

import argparse
from typing import Any

from bench.commands import _bench_common as common
from bench.sequences import sweep
from bench.thrust_map import fit_sweep_run


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "sweep", help="slow throttle ramp: thrust, current and speed against command",
        description="Ramps the ESC command slowly and records thrust, current and speed "
                    "(Fig. C.13, C.14). Fits the static command->thrust map and stores it "
                    "with the rig (unless --no-save-map), for the thrust steps. A shipped "
                    "(or read-only) rig is never rewritten: the rig is copied to "
                    "OUT/rigs/ with the map beside it, and step/sweep with the same --out "
                    "use that copy.")
    common.add_common_arguments(p)
    p.add_argument("--start-us", type=float, default=1100.0)
    p.add_argument("--end-us", type=float, default=1900.0)
    p.add_argument("--duration", type=float, default=20.0, help="ramp time in seconds (20)")
    p.add_argument("--no-save-map", action="store_true", help="do not store the fitted map")
    p.set_defaults(func=handler)


def build(args: argparse.Namespace):
    seq = sweep(args.start_us, args.end_us, args.duration)
    return common.with_limits(seq, common.parse_limits(args.limit))


def measure_map(rig: Any, args: argparse.Namespace, save: bool = True) -> tuple[Any, int]:
    """Run a sweep, fit the map, store it with the rig; returns (rig, exit code)."""
    from bench.rig import is_shipped_rig, map_goes_to_copy, rig_copy_path, save_thrust_map

    defaults = {"start_us": 1100.0, "end_us": 1900.0, "duration": 20.0}
    for key, value in defaults.items():
        if not hasattr(args, key):
            setattr(args, key, value)
    outcome = common.execute(rig, build(args), args)
    code = common.report(outcome)
    if code:
        return rig, code
    fit = fit_sweep_run(outcome.run_dir)
    tm = fit.thrust_map
    print(f"static thrust map: {tm.command_us[0]:.0f}-{tm.command_us[-1]:.0f} us -> "
          f"{tm.thrust_n[0]:.3f}-{tm.thrust_n[-1]:.3f} N, fit residual "
          f"{fit.residual_rms_n * 1000:.1f} mN rms ({outcome.run_dir / 'static_map.json'})")
    if save and map_goes_to_copy(rig):  # shipped/read-only rig: store a copy with the map
        original = rig.path
        why = "a shipped rig" if is_shipped_rig(original) else "not writable"
        dest = rig_copy_path(original, args.out).parent
        rig = save_thrust_map(rig, tm.command_us.tolist(), tm.thrust_n.tolist(), dest_dir=dest)
        print(f"{original} is {why}, left unchanged: the rig with the new map is {rig.path} "
              f"(map {rig.thrust_map_path.name} beside it); `--rig {rig.path}` uses it, as "
              f"do step and sweep with --out {args.out}")
    elif save:
        rig = save_thrust_map(rig, tm.command_us.tolist(), tm.thrust_n.tolist())
        print(f"stored with the rig: {rig.thrust_map_path}")
    return rig, 0


def handler(args: argparse.Namespace) -> int:
    rig = common.load_rig_from_args(args, prefer_out_copy=True)
    if args.dry_run:
        common.print_dry_run(rig, build(args))
        return 0
    _, code = measure_map(rig, args, save=not args.no_save_map)
    return code
