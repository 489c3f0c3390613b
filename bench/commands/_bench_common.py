"""Shared pieces of the bench commands (step, sweep): rig loading, progress, running."""

from __future__ import annotations

import argparse
import contextlib
import math
import signal
import sys
import threading
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

from rich.console import Console
from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

from bench.cli_support import check_writable
from bench.errors import RecordingError, RigError
from bench.indexed_run import RunInterrupted, RunRecordingFailed
from bench.run_budget import Budget, check_budget, project, row_rate_hz
from bench.runner import RunOptions
from bench.safety import LIMIT_FIELDS, effective_limits
from bench.sequences import Segment, Sequence, format_plan
from bench.session import RunOutcome, plan_for, run_sequence

DEFAULT_OUT = Path("runs")


def err_console() -> Console:
    return Console(stderr=True)


def add_common_arguments(p: argparse.ArgumentParser) -> None:
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


def check_limits(rig: Any, seq: Sequence) -> None:
    """Refuse a sequence (or --limit) that would loosen the rig's limits before anything
    is shown or opened: the dry run says what the run would say."""
    effective_limits(rig.limits, seq.limits, source=f"sequence {seq.name!r}")


def check_budget_of(rig: Any, seq: Sequence, args: argparse.Namespace) -> Budget:
    """The plan's projected rig time and samples size, refused beyond the bounds of
    ``bench.run_budget`` (above the confirmation bounds unless ``--yes``)."""
    budget = project(plan_for(rig, seq, dry_run=True).duration_s, row_rate_hz(rig))
    check_budget(budget, seq.where, bool(getattr(args, "yes", False)))
    return budget


def with_limits(seq: Sequence, extra: Mapping[str, float]) -> Sequence:
    if not extra:
        return seq
    from dataclasses import replace

    return replace(seq, limits={**seq.limits, **extra})


def print_dry_run(rig: Any, seq: Sequence) -> None:
    check_limits(rig, seq)
    plan = plan_for(rig, seq, dry_run=True)
    print(f"rig {rig.name} ({rig.path}); ESC {rig.esc.idle_us:g} us idle, "
          f"{rig.esc.min_us:g}-{rig.esc.max_us:g} us at {rig.esc.frame_rate_hz:g} Hz")
    print(format_plan(plan))
    print(project(plan.duration_s, row_rate_hz(rig)).describe())


def execute(rig: Any, seq: Sequence, args: argparse.Namespace,
            extra_meta: Mapping[str, Any] | None = None) -> RunOutcome:
    """Run one sequence with a progress bar on stderr (and the live view if asked)."""
    from drivers.factory import open_rig

    check_limits(rig, seq)
    check_budget_of(rig, seq, args)
    check_writable(args.out, "--out", folder=True)
    options = RunOptions(tick_s=args.tick, realtime=bool(args.realtime or args.live))
    stop = threading.Event()
    total = plan_for(rig, seq).duration_s
    progress = Progress(TextColumn("{task.description}"), BarColumn(),
                        TextColumn("{task.completed:6.1f}/{task.total:.1f} s rig time"),
                        TimeElapsedColumn(), console=err_console())
    task = progress.add_task(seq.name, total=total)

    def on_progress(t: float, _total: float, seg: Segment) -> None:
        progress.update(task, completed=t, description=f"{seq.name} [{seg.label}]")

    meta = {"command_line": ["rotorbench", *sys.argv[1:]], **dict(extra_meta or {})}

    def work(on_rows: Callable | None) -> RunOutcome:
        return run_sequence(rig, seq, args.out, open_rig, seed=args.seed, options=options,
                            on_rows=on_rows, on_progress=on_progress, stop_event=stop,
                            extra_meta=meta)

    with say_where_an_interrupted_run_went("run", "ESC idle and disarmed"):
        with progress, _sigterm_as_interrupt(stop), \
                erase_on_user_error(progress):
            if args.live:
                from bench.live import run_with_live_view

                outcome = run_with_live_view(work)
            else:
                outcome = work(None)
            progress.update(task, completed=outcome.result.t_end_s)
    return outcome


@contextlib.contextmanager
def say_where_an_interrupted_run_went(what: str, safe: str):
    """Ctrl-C / SIGTERM: one line on stderr naming the run folder and its recorded status
    (after the progress bar has stopped), then the interrupt goes on (exit 130). A run
    aborted by a failed write (disk full) becomes the one-line error (exit 2) saying the
    same in this bench's words: what was made safe, where the partial run is."""
    try:
        yield
    except RunInterrupted as exc:
        print(f"rotorbench: {exc.summary(what, safe)}", file=sys.stderr, flush=True)
        raise
    except RunRecordingFailed as exc:
        raise RecordingError(exc.summary(what, safe)) from None


@contextlib.contextmanager
def erase_on_user_error(progress: Progress):
    """A user error (an exception with ``exit_code``) leaves only its one line on stderr:
    the progress bar is made transient, so it is erased (terminal) or never printed."""
    try:
        yield
    except Exception as exc:
        if getattr(exc, "exit_code", None) is not None:
            progress.live.transient = True
            if not progress.console.is_interactive:  # a file or pipe: not even a blank line
                progress.console.quiet = True
        raise


@contextlib.contextmanager
def _sigterm_as_interrupt(stop: threading.Event):
    """``kill PID`` (SIGTERM) ends a run like Ctrl-C: safe stop, record, exit 130."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def on_term(*_: object) -> None:
        stop.set()
        raise KeyboardInterrupt("SIGTERM")  # the runner is on this thread: interrupt it now

    previous = signal.signal(signal.SIGTERM, on_term)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


def report(outcome: RunOutcome) -> int:
    res = outcome.result
    print(f"{outcome.run_dir}: {res.status}: {res.reason} ({res.rows} samples, "
          f"{res.t_end_s:.2f} s)")
    if res.safe_stop_errors:
        print(f"warning: safe stop reported: {'; '.join(res.safe_stop_errors)}", file=sys.stderr)
    return 0 if res.status == "success" else 1
