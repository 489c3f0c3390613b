"""Running a plan with a progress bar: what the CLI and the console's tests share for both
benches (a propulsion sequence, or every stage of an IMU calibration).

The bar goes to stderr; the lines a user reads (the result, where an interrupted run
went) go through the :class:`JobOutput` the command passes in, so a job prints nothing
itself. Ctrl-C or SIGTERM make the run safe (ESC idle and disarmed, or
the hexapod stopped), record it and end with one line naming the run folder; a failed
write (disk full) becomes a one-line error; a user error leaves only its own line.
"""

from __future__ import annotations

import contextlib
import sys
import threading
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from rich.console import Console
from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

from bench.engine.safety import effective_limits
from bench.engine.sigterm import sigterm_as_interrupt
from bench.errors import RecordingError
from bench.paths.outputs import check_writable
from bench.plan_runner.runner import HexapodRunOptions, RunOptions
from bench.plan_runner.session import RunOutcome, plan_for, run_sequence
from bench.plans.calibration_sequences import HexapodSegment
from bench.plans.run_budget import Budget, check_budget, project, row_rate_hz
from bench.plans.sequences import Plan, Segment
from bench.plans.sequences import Sequence as PlanSequence
from bench.store.indexed_run import RunInterrupted, RunRecordingFailed

if TYPE_CHECKING:  # the calibration stages (pandas, the IMU fits) load only for a calibration
    from bench.jobs.calibration_stages import CalibrationRun

__all__ = [
    "JobOutput",
    "check_budget_of",
    "check_limits",
    "erase_on_user_error",
    "err_console",
    "report",
    "run_calibration_with_progress",
    "run_with_progress",
    "say_where_an_interrupted_run_went",
    "sigterm_as_interrupt",
]


@dataclass(frozen=True)
class JobOutput:
    """Where a job's words go, given by the command that runs it: ``out`` the result
    lines (stdout), ``err`` notes and warnings (stderr), one line a call."""

    out: Callable[[str], None]
    err: Callable[[str], None]


def err_console() -> Console:
    return Console(stderr=True)


def _progress_bar() -> Progress:
    return Progress(TextColumn("{task.description}"), BarColumn(),
                    TextColumn("{task.completed:6.1f}/{task.total:.1f} s rig time"),
                    TimeElapsedColumn(), console=err_console())


def check_limits(rig: Any, seq: PlanSequence) -> None:
    """Refuse a sequence (or --limit) that would loosen the rig's limits before anything
    is shown or opened: the dry run says what the run would say."""
    effective_limits(rig.limits, seq.limits, source=f"sequence {seq.name!r}",
                     thrust_setpoints_n=seq.thrust_setpoints_n)


def check_budget_of(rig: Any, seq: PlanSequence, confirmed: bool) -> Budget:
    """The plan's projected rig time and samples size, refused beyond the bounds of
    ``bench.plans.run_budget`` (above the confirmation bounds unless ``confirmed``: --yes)."""
    check_budget(project(seq.duration_s, row_rate_hz(rig)), seq.where, confirmed)  # cheap
    budget = project(plan_for(rig, seq, dry_run=True).duration_s, row_rate_hz(rig))
    check_budget(budget, seq.where, confirmed)
    return budget


def command_line() -> list[str]:
    """This command as run.json records it, every URL's password replaced by ``***`` (a
    ``--store postgresql://user:pw@...`` must not reach a run record or the catalog)."""
    from bench.store.store_url import redact

    return ["rotorbench", *(redact(a) for a in sys.argv[1:])]


def run_with_progress(rig: Any, seq: PlanSequence, out: Path, *, seed: int | None = None,
                      options: RunOptions | None = None, live: bool = False,
                      confirmed: bool = False,
                      extra_meta: Mapping[str, Any] | None = None,
                      output: JobOutput) -> RunOutcome:
    """Run one propulsion sequence with a progress bar on stderr (and the live view if
    ``live``); the checks (limits, budget, writable ``out``) come before any device."""
    from drivers.factory import open_rig

    check_limits(rig, seq)
    check_budget_of(rig, seq, confirmed)
    check_writable(out, "--out", folder=True)
    options = options or RunOptions()
    stop = threading.Event()
    total = plan_for(rig, seq).duration_s
    progress = _progress_bar()
    task = progress.add_task(seq.name, total=total)

    def on_progress(t: float, _total: float, seg: Segment) -> None:
        progress.update(task, completed=t, description=f"{seq.name} [{seg.label}]")

    meta = {"command_line": command_line(), **dict(extra_meta or {})}

    def work(on_rows: Callable | None) -> RunOutcome:
        return run_sequence(rig, seq, out, open_rig, seed=seed, options=options,
                            on_rows=on_rows, on_progress=on_progress, stop_event=stop,
                            extra_meta=meta)

    with say_where_an_interrupted_run_went("run", "ESC idle and disarmed", output.err):
        with progress, sigterm_as_interrupt(stop), erase_on_user_error(progress):
            if live:
                from bench.live import run_with_live_view

                outcome = run_with_live_view(work, tell=output.err)
            else:
                outcome = work(None)
            progress.update(task, completed=outcome.result.t_end_s)
    return outcome


def run_calibration_with_progress(rig: Any, plans: Sequence[Plan], runs: Path, *,
                                  quick: bool, options: HexapodRunOptions,
                                  extra_meta: Mapping[str, Any] | None = None,
                                  output: JobOutput) -> CalibrationRun:
    """Every stage of an IMU calibration with one progress bar over all stages."""
    from bench.jobs.calibration_stages import run_calibration

    total = sum(p.duration_s for p in plans)
    offsets = np.concatenate([[0.0], np.cumsum([p.duration_s for p in plans])])
    progress = _progress_bar()
    task = progress.add_task("calibration", total=total)
    stage = {"i": 0}
    stop = threading.Event()

    def on_stage(i: int, plan: Plan) -> None:
        stage["i"] = i
        progress.update(task, completed=offsets[i],
                        description=f"{i + 1}/{len(plans)} {plan.sequence.name}")

    def on_progress(t: float, _total: float, seg: HexapodSegment) -> None:
        i = stage["i"]
        progress.update(task, completed=min(offsets[i] + t, total),
                        description=f"{i + 1}/{len(plans)} {plans[i].sequence.name} "
                                    f"[{seg.phase}: {seg.label}]")

    seqs: list[PlanSequence] = [p.sequence for p in plans]
    meta = {"command_line": command_line(), **dict(extra_meta or {})}
    with say_where_an_interrupted_run_went("calibration stage", "hexapod stopped",
                                           output.err), \
            progress, sigterm_as_interrupt(stop), erase_on_user_error(progress):
        return run_calibration(rig, runs, quick=quick, options=options, sequences=seqs,
                               on_stage=on_stage, on_progress=on_progress, stop_event=stop,
                               extra_meta=meta)


@contextlib.contextmanager
def say_where_an_interrupted_run_went(what: str, safe: str,
                                      err: Callable[[str], None]) -> Iterator[None]:
    """Ctrl-C / SIGTERM: one line to ``err`` (stderr) naming the run folder and its recorded status
    (after the progress bar has stopped), then the interrupt goes on (exit 130). A run
    aborted by a failed write (disk full) becomes the one-line error (exit 2) saying the
    same in this bench's words: what was made safe, where the partial run is."""
    try:
        yield
    except RunInterrupted as exc:
        err(f"rotorbench: {exc.summary(what, safe)}")
        raise
    except RunRecordingFailed as exc:
        raise RecordingError(exc.summary(what, safe)) from None


@contextlib.contextmanager
def erase_on_user_error(progress: Progress) -> Iterator[None]:
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


def report(outcome: RunOutcome, output: JobOutput) -> int:
    """One line for the finished run (and the safe stop's complaints); the exit code."""
    res = outcome.result
    output.out(f"{outcome.run_dir}: {res.status}: {res.reason} ({res.rows} samples, "
               f"{res.t_end_s:.2f} s)")
    if res.safe_stop_errors:
        output.err(f"warning: safe stop reported: {'; '.join(res.safe_stop_errors)}")
    return 0 if res.status == "success" else 1
