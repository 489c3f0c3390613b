"""Helpers every CLI command shares (the one home: commands never import each other).

The bench commands' common arguments (``--rig``, ``--out``, ``--limit``, ...), reading
them (the rig, the limits, the loop options) and the dry-run listing; and the output
check every writing command makes on its output path before any work.

A command that would run for minutes (a demo, a calibration on the rig) and then fail to
write its result wastes the run; a traceback at the end says nothing useful. So each
command names its outputs up front and :func:`check_writable` refuses, in one line with
exit code 2, a path that cannot be written: a regular file where a folder must be (or
the reverse), a missing folder the command does not create, a folder the user may not
write in (read-only, immutable, read-only file system). Writability is probed by creating
and removing a hidden temporary file, the only test that is right for every user
(``os.access`` says yes to root on a read-only folder, no on some network mounts).
"""

from __future__ import annotations

import argparse
import math
import os
import tempfile
from pathlib import Path
from typing import Any

from bench.errors import RigError

__all__ = ["DEFAULT_OUT", "add_common_arguments", "check_writable", "load_rig_from_args",
           "parse_limits", "print_dry_run", "run_options_from_args"]

DEFAULT_OUT = Path("runs")


def check_writable(path: Path, flag: str, *, folder: bool, beside: bool = False,
                   make_parents: bool = True) -> Path:
    """Refuse (``RigError``) an output ``path`` that cannot be written; return it.

    ``folder``: the output is a folder (a run root, a report) rather than a file.
    ``beside``: the folder is built beside its final name and renamed into place, so
    its parent must be writable even when the folder exists.
    ``make_parents``: the command creates missing parent folders; if not, the parent
    must exist.
    """
    path = Path(path)
    where = f"{flag} {path}" if flag else str(path)
    if path.exists() or path.is_symlink():
        if folder and not path.is_dir():
            raise RigError(f"{where}: is a file; expected a folder")
        if not folder and path.is_dir():
            raise RigError(f"{where}: is a folder; expected the name of the file to write")
    # where the new entries go: into an existing folder, else beside the path
    target = path if folder and path.is_dir() and not beside else path.parent
    anchor = target
    while not anchor.exists() and anchor != anchor.parent:
        anchor = anchor.parent  # the nearest folder that exists: the command creates the rest
    if not anchor.is_dir():
        raise RigError(f"{where}: {anchor} is a file, not a folder")
    if not make_parents and anchor != target:
        raise RigError(f"{where}: folder {target} does not exist")
    problem = _probe(anchor)
    if problem is not None:
        raise RigError(f"{where}: cannot write in {anchor} ({problem})")
    return path


def _probe(folder: Path) -> str | None:
    """Why a new file cannot be created in ``folder`` (None if it can)."""
    try:
        fd, name = tempfile.mkstemp(prefix=".rotorbench-probe-", dir=folder)
    except OSError as exc:
        return exc.strerror or str(exc)
    os.close(fd)
    os.unlink(name)
    return None


# --- the bench commands' arguments (step, sweep, console) -----------------------------------
def add_common_arguments(p: argparse.ArgumentParser) -> None:
    from bench.safety import LIMIT_FIELDS

    p.add_argument("--rig", type=Path, default=None,
                   help="rig file (TOML); default: the simulated rig fixtures/rigs/sim.toml")
    p.add_argument("--out", type=Path, default=DEFAULT_OUT,
                   help="output root for run folders and runs.sqlite (default: ./runs)")
    p.add_argument("--esc-mode", choices=("complementary", "diode", "stock"), default=None,
                   help="ESC switching scheme / firmware (overrides the rig file)")
    p.add_argument("--seed", type=int, default=None, help="seed of the simulated rig")
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


def load_rig_from_args(args: argparse.Namespace, prefer_out_copy: bool = False) -> Any:
    """The rig of ``--rig`` (default: the sim rig), with ``--esc-mode`` applied.

    ``prefer_out_copy``: for a read-only rig (shipped, or not writable) use the copy an
    earlier sweep stored under ``<out>/rigs/`` with its measured map, if there is one.
    """
    from bench.rig import default_rig_path, load_rig, map_goes_to_copy, rig_copy_path

    rig = load_rig(args.rig or default_rig_path())
    if prefer_out_copy and map_goes_to_copy(rig):
        copy = rig_copy_path(rig.path, args.out)
        if copy.is_file():
            print(f"rig file: {copy} (the copy of read-only {rig.path} that holds the "
                  "map a sweep measured)")
            rig = load_rig(copy)
    if args.esc_mode:
        rig = rig.with_esc_mode(args.esc_mode)
    return rig


def parse_limits(items: list[str]) -> dict[str, float]:
    """``--limit NAME=VALUE`` items as a dict (names of ``bench.safety.LIMIT_FIELDS``)."""
    from bench.safety import LIMIT_FIELDS

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
    from bench.runner import RunOptions

    return RunOptions(tick_s=args.tick, realtime=bool(args.realtime or args.live))


def print_dry_run(rig: Any, seq: Any) -> None:
    """The dry run: the rig's ESC, every step with times and commands, the projection."""
    from bench.run_budget import project, row_rate_hz
    from bench.safety import effective_limits
    from bench.sequences import format_plan
    from bench.session import plan_for

    effective_limits(rig.limits, seq.limits, source=f"sequence {seq.name!r}")
    plan = plan_for(rig, seq, dry_run=True)
    print(f"rig {rig.name} ({rig.path}); ESC {rig.esc.idle_us:g} us idle, "
          f"{rig.esc.min_us:g}-{rig.esc.max_us:g} us at {rig.esc.frame_rate_hz:g} Hz")
    print(format_plan(plan))
    print(project(plan.duration_s, row_rate_hz(rig)).describe())
