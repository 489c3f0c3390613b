"""``rotorbench console``: the bench console window (manual control, plans, live plots,
limits, history), with the rig and every run in this process and the window in its own."""

from __future__ import annotations

import argparse
import multiprocessing as mp
import os
import sys
from pathlib import Path
from typing import Any

from bench.cli_args.option_values import seed_arg
from bench.cli_args.run_args import load_rig_from_args, parse_limits
from bench.cli_args.store_args import DEFAULT_OUT, add_store_args, publish_runs, recording_store
from bench.errors import RigError
from bench.paths.outputs import check_figure_path, check_writable

SELFTEST_MIN_FPS = 30.0
SELFTEST_MIN_SIZE = (800, 500)


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "console", help="the bench console: arm, throttle, stop, plans, live plots, history",
        description="A window to run the stand by hand and by plan (needs the live extra: "
                    "pip install 'rotorbench[live]'). Stop (button, Space, Esc) puts the ESC "
                    "at idle and disarms it; closing the window, a crash of it or a frozen "
                    "window (no heartbeat for 1 s) does the same. On an IMU-bench rig the IMU "
                    "tab runs the Paper A calibration.")
    p.add_argument("--rig", type=Path, default=None,
                   help="rig file (TOML); default: the simulated rig bench/data/rigs/sim.toml")
    p.add_argument("--out", type=Path, default=DEFAULT_OUT,
                   help="output root for run folders and runs.sqlite (default: ./runs); with "
                        "a lab --store, the data location")
    add_store_args(p, records=True)
    p.add_argument("--seed", type=seed_arg, default=None, help="seed of the simulated rig")
    p.add_argument("--limit", action="append", default=[], metavar="NAME=VALUE",
                   help="start with a tighter limit (loosening is refused)")
    p.add_argument("--rate", type=float, default=None,
                   help="throttle rate limit in us/s (default 400: full range in 2.5 s)")
    p.add_argument("--tick", type=float, default=0.02, help="command/read period (s)")
    p.add_argument("--window", type=float, default=5.0, help="seconds shown in the plots")
    p.add_argument("--selftest", action="store_true",
                   help="headless check: arm, throttle 30 %%, hold 3 s, stop, screenshot, "
                        "print the plot refresh rate; exit 0 if all worked")
    p.add_argument("--screenshot", type=Path, default=None,
                   help="with --selftest: where to save the window (PNG)")
    p.add_argument("--min-fps", type=float, default=None,
                   help="with --selftest: the plot refresh rate it must reach (default 30)")
    p.set_defaults(func=handler, esc_mode=None)


def _check_selftest_args(args: argparse.Namespace) -> None:
    """``--screenshot`` and ``--min-fps`` belong to ``--selftest``; a rate is a number >= 0."""
    if not args.selftest:
        for flag, value in (("--screenshot", args.screenshot), ("--min-fps", args.min_fps)):
            if value is not None:
                raise RigError(f"{flag}: only applies with --selftest")
        return
    if args.min_fps is None:
        args.min_fps = SELFTEST_MIN_FPS
    if not 0 <= args.min_fps < 1000:  # nan and inf fail too
        raise RigError(f"--min-fps {args.min_fps:g}: expected a refresh rate in frames/s, "
                       "0 <= rate < 1000")


def handler(args: argparse.Namespace) -> int:
    from bench.console.link import BenchLink
    from bench.console.manual import DEFAULT_RATE_US_S
    from bench.console.server import ConsoleBench
    from bench.live import _qt_binding_missing, check_display
    from bench.plan_runner.runner import RunOptions
    from bench.rig.rig import is_imu_rig, load_imu_rig

    store = recording_store(args, warn=lambda line: print(line, file=sys.stderr))
    # a lab store records into the spool, published at exit
    imu = args.rig is not None and is_imu_rig(args.rig)
    rig = load_imu_rig(args.rig) if imu and args.rig is not None else load_rig_from_args(args)
    if imu and (args.limit or args.selftest):
        raise RigError(f"{args.rig}: an IMU-bench rig; --limit and --selftest are for "
                       "propulsion rigs (the hexapod's limits are in its rig file)")
    limits = {} if imu else _tightened(rig, parse_limits(args.limit))
    if args.rate is not None and not (args.rate > 0 and args.rate < 1e5):
        raise RigError(f"--rate {args.rate:g}: expected a rate limit in us/s > 0")
    if not 0 < args.window <= 60:  # written so that nan fails too
        raise RigError(f"--window {args.window:g}: expected 0 < seconds <= 60")
    _check_selftest_args(args)
    options = RunOptions(tick_s=args.tick, realtime=True)
    check_writable(args.out, "--out", folder=True)
    if args.selftest:
        os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")
        if args.screenshot is None:
            args.screenshot = args.out / "console-selftest.png"
        check_figure_path(args.screenshot, "--screenshot", suffixes=(".png",))
    check_display("console", "")
    problem = _qt_binding_missing()
    if problem is not None:
        raise RigError(problem.replace("--live", "console"))
    ctx = mp.get_context("spawn")  # never fork a process that holds devices
    link = BenchLink(capacity=int(25_000 * args.window * 1.2), ctx=ctx)
    bench = ConsoleBench(rig, args.out, link, seed=args.seed, options=options,
                         rate_us_s=args.rate or DEFAULT_RATE_US_S)
    bench.limits = limits
    selftest = {"screenshot": str(args.screenshot)} if args.selftest else None
    from bench.console.gui_main import window_main

    proc = ctx.Process(target=window_main, name="rotorbench-console", daemon=True,
                       args=(link.gui_args(), str(args.out), selftest, args.window))
    proc.start()
    link.proc = proc
    try:
        why = bench.serve()
    finally:
        bench.wait()
        proc.join(5)
        if proc.is_alive():
            proc.terminate()
            proc.join(3)
    publish_runs(store, tell=print)
    if bench.fatal:
        raise RigError(bench.fatal)
    for info in bench.finished:
        print(f"{info['run_dir']}: {info['kind']} {info['status']}: {info['reason']} "
              f"({info['rows']} samples, {info['t_end_s']:.2f} s)")
    if not args.selftest:
        print(f"console: {why}")
        return 0
    return _selftest_verdict(bench, rig, args.min_fps)


def _tightened(rig: Any, extra: dict[str, float]) -> dict[str, float]:
    from bench.engine.safety import effective_limits

    return effective_limits(rig.limits, extra, source="--limit")


def _selftest_verdict(bench: Any, rig: Any, min_fps: float) -> int:
    """Print the refresh rate and check what the self-test promises; 0 if all holds."""
    import pandas as pd

    result = getattr(bench, "selftest", None)
    problems = []
    if result is None:
        problems.append(f"the window ended without a self-test result ({bench.lost_reason})")
        result = {}
    elif not result.get("ok"):
        problems.append(result.get("problem", "failed"))
    fps = float(result.get("frames_per_s", 0.0))
    if result:
        print(f"{fps:.0f} frames/s")
    if result.get("ok"):
        if fps < min_fps:
            problems.append(f"plot refresh {fps:.1f} frames/s < {min_fps:g}")
        w, h = result["size"]
        if w < SELFTEST_MIN_SIZE[0] or h < SELFTEST_MIN_SIZE[1]:
            problems.append(f"screenshot {w}x{h} smaller than 800x500")
        else:
            print(f"screenshot: {result['screenshot']} ({w}x{h})")
        info = result["finished"]
        if info["status"] != "success":
            problems.append(f"run {info['status']}: {info['reason']}")
        samples = pd.read_parquet(Path(info["run_dir"]) / "samples.parquet",
                                  columns=["throttle_us"])["throttle_us"].to_numpy()
        idle = float(rig.esc.idle_us)
        top = float(samples.max()) if samples.size else idle
        print(f"recorded throttle: up to {top:.0f} us, last {samples[-1]:.0f} us "
              f"(idle {idle:.0f} us)" if samples.size else "recorded throttle: no samples")
        if not samples.size or top <= idle:
            problems.append("the recorded throttle never rose above idle")
        elif samples[-1] != idle:
            problems.append(f"the recorded throttle ends at {samples[-1]:.0f} us, not idle")
    for p in problems:
        print(f"selftest: FAIL: {p}", file=sys.stderr)
    if not problems:
        print("selftest: ok")
    return 1 if problems else 0
