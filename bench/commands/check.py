"""``rotorbench check --rig FILE``: connect to every device of a rig and report what answers.

The devices are read on the wall clock as in a run, so the bench is raised for the check as
for a run (``bench.engine.host_priority``): a rate it reports is one a run would get, not
what a busy machine left the reader."""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

from bench.engine.host_priority import HostPriority
from bench.errors import RigError
from bench.paths.outputs import check_writable

#: the longest wait for one device a user may ask (time arithmetic overflows on 1e308)
MAX_TIMEOUT_S = 3600.0


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "check", help="connect to every device of a rig file and report what answers",
        description="Opens each device of the rig on its own and waits for a sign of life "
                    "(samples from sensors; identification or bus traffic from the ESC). "
                    "Nothing is armed or moved. One line per device; exit 0 when all "
                    "answer, 2 otherwise. An IMU-bench rig ([rig] kind = \"imu\") is "
                    "checked through the IMU factory: the hexapod identifies itself and is "
                    "stopped, the IMUs must deliver samples.")
    p.add_argument("--rig", type=Path, default=None,
                   help="rig file (TOML), propulsion or IMU bench; default: the simulated rig "
                        "bench/data/rigs/sim.toml")
    p.add_argument("--timeout", type=float, default=2.0,
                   help="seconds to wait for each device (default 2)")
    p.add_argument("--json", action="store_true", help="print JSON lines instead of a table")
    p.add_argument("--deep", action="store_true",
                   help="bring-up report at rest: identity and firmware, limits stated by the "
                        "device against the rig file's, achieved rate and drops, noise floor, "
                        "clock skew; saved as <rig>.bringup.json beside the rig file")
    p.add_argument("--seconds", type=float, default=None,
                   help="--deep: seconds to listen at rest (default 2)")
    p.add_argument("--save", type=Path, default=None,
                   help="--deep: where to save the report (default: beside the rig file)")
    p.set_defaults(func=handler)


def _fmt(v: object) -> str:
    return f"{v:.4g}" if isinstance(v, float) else str(v)


def deep(args: argparse.Namespace, path: Path) -> int:
    """``--deep``: the bring-up report (bench/rig/bringup.py), printed and saved."""
    from bench.engine.recorder import atomic_write_json
    from bench.rig.bringup import bringup_report
    from bench.rig.rig import load_any_rig

    seconds = 2.0 if args.seconds is None else args.seconds
    if not (math.isfinite(seconds) and 0 < seconds <= 600):
        raise RigError(f"--seconds: expected 0 < seconds <= 600, got {seconds:g}")
    out = args.save or path.with_name(f"{path.stem}.bringup.json")
    rig = load_any_rig(path)
    check_writable(out, "--save", folder=False, inputs=(path,))  # before listening
    try:  # the folder too, as every other command's output: the report is not lost after
        out.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise RigError(f"--save {out}: cannot create its folder {out.parent} "
                       f"({exc.strerror or exc})") from None
    report = bringup_report(rig, seconds)
    atomic_write_json(out, report)
    if args.json:
        for d in report["devices"]:
            print(json.dumps(d))
    else:
        for d in report["devices"]:
            ident = ", ".join(f"{k} {_fmt(v)}" for k, v in d["identity"].items())
            print(f"{d['role']:<10} {d['url']}  {ident}")
            for name, lim in d["limits"].items():
                print(f"{'':<10}   limit {name}: device {lim['device']}, rig {lim['rig']}")
            if "controller" in d:
                print(f"{'':<10}   controller {json.dumps(d['controller'])}")
            if d["role"] in ("esc", "hexapod"):
                continue
            print(f"{'':<10}   rate {d['rate_hz']:.1f} samples/s (stated {d['stated_rate_hz']}),"
                  f" dropped {d['dropped']}, longest gap {d['longest_gap_s']} s, lag "
                  f"{_fmt(d['lag_s'])} s, skew {_fmt(d['skew_s'])} s")
            for col, st in d["noise"].items():
                print(f"{'':<10}   {col}: mean {st['mean']:.6g}, rms {st['rms']:.3g}")
    print(f"saved {out}")
    return 0


def handler(args: argparse.Namespace) -> int:
    from bench.rig.rig import default_rig_path

    if not (math.isfinite(args.timeout) and 0 < args.timeout <= MAX_TIMEOUT_S):
        raise RigError(f"--timeout: expected seconds > 0 per device (at most "
                       f"{MAX_TIMEOUT_S:g}), got {args.timeout:g}")
    path = args.rig or default_rig_path()
    with HostPriority(True):  # the rates it reports are the ones a run would get
        return deep(args, path) if args.deep else _check(args, path)


def _check(args: argparse.Namespace, path: Path) -> int:
    """The plain check: one line per device."""
    from bench.rig.rig import is_imu_rig, load_imu_rig, load_rig

    for flag, value in (("--seconds", args.seconds), ("--save", args.save)):
        if value is not None:
            raise RigError(f"{flag}: only applies with --deep")
    from drivers.check import check_rig

    rig = load_imu_rig(path) if is_imu_rig(path) else load_rig(path)
    reports = check_rig(rig, timeout_s=args.timeout)
    if args.json:
        for r in reports:
            print(json.dumps({"role": r.role, "url": r.url, "ok": r.ok, "detail": r.detail}))
    else:  # one line per device, never wrapped (grep-able)
        width = max(len(r.url) for r in reports)
        rw = max(10, *(len(r.role) for r in reports))
        for r in reports:
            print(f"{r.role:<{rw}} {r.url:<{width}}  {'ok' if r.ok else 'FAIL':<4}  {r.detail}")
    return 0 if all(r.ok for r in reports) else 2
