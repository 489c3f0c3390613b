"""Running a sweep: its chunks flown here or on a Dask cluster, with resume and a progress bar.

Three executors give the same rows (the tasks are pure: ``optimizer.sweep.fly_rows``):
this process (``--workers 1``, the default), a ``distributed.LocalCluster`` of worker
processes with one thread each (``--workers K``), or an existing cluster
(``--scheduler tcp://host:8786``, e.g. dask-jobqueue on SLURM). ``dask[distributed]`` is
imported only for the last two (the ``sweep`` extra).

Results arrive as chunks finish (``distributed.as_completed``) and each is written as a
part at once (``bench.jobs.sweep_parts``), so a sweep stopped by Ctrl-C or a lost
scheduler keeps them and the same command resumes. A worker that dies costs nothing:
the scheduler runs its tasks again elsewhere, and a design's row is kept once.
"""

from __future__ import annotations

import contextlib
import importlib.util
import logging
import time
import uuid
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pandas as pd
import pyarrow as pa
from rich.console import Console
from rich.progress import (
    BarColumn,
    MofNCompleteColumn,
    Progress,
    ProgressColumn,
    Task,
    TextColumn,
    TimeRemainingColumn,
)
from rich.text import Text

from bench.jobs.sweep_lock import sweep_lock
from bench.jobs.sweep_memory import available_memory, check_fits
from bench.jobs.sweep_parts import OutputLost, Parts, in_plan_order, table_of, write_atomic
from bench.jobs.sweep_scheduler import probe
from optimizer.errors import RequestError
from optimizer.sweep.chunks import check_chunk_size, chunk_size, split
from optimizer.sweep.fly_rows import Chunk, fly_chunk

#: seconds to reach a scheduler before ``--scheduler`` is refused as unreachable
CONNECT_TIMEOUT_S = 4.0
#: chunks in flight per worker thread (the rest wait here, not in the scheduler's memory)
IN_FLIGHT_PER_SLOT = 8
MIN_IN_FLIGHT = 64
EXTRA = "pip install 'rotorbench[sweep]'"


class SweepLost(RuntimeError):
    """The cluster went away (or a chunk kept killing workers): the finished chunks are
    kept and the same command resumes. One line, exit 1."""

    exit_code = 1


@dataclass(frozen=True)
class Executor:
    """Where chunks are flown: this process (``workers`` 1, no ``scheduler``), a
    LocalCluster of ``workers`` processes (``local`` forces one for a single worker:
    the benchmark's overhead measure), or the cluster at ``scheduler``."""

    workers: int = 1
    scheduler: str | None = None
    local: bool = False

    def check(self) -> Executor:
        if self.workers < 1:
            raise RequestError(f"--workers: expected a number of worker processes >= 1, got "
                               f"{self.workers}")
        if self.scheduler is not None and self.workers != 1:
            raise RequestError("--workers and --scheduler: give one (--scheduler uses the "
                               "workers of that cluster)")
        return self

    @property
    def in_process(self) -> bool:
        return self.scheduler is None and self.workers == 1 and not self.local


@dataclass
class SweepResult:
    """The rows of every planned design, in plan order, and how the run went."""

    table: pa.Table
    seconds: float
    resumed: int  # designs found finished in the parts
    flown: int  # designs flown by this run
    chunk_size: int

    @property
    def errors(self) -> int:
        """Designs that did not fly (their rows carry the error)."""
        return len(self.table) - self.table["error"].null_count


def run_sweep(plan: pd.DataFrame, maneuvers: Sequence[str], spec: Mapping[str, Any], *,
              out: Path | None = None, executor: Executor = Executor(),
              chunk: int | None = None, progress: bool = True,
              on_rows: Callable[[int, int], None] | None = None) -> SweepResult:
    """Fly every design of ``plan`` (``optimizer.sweep.designs.plan_designs``) through
    ``maneuvers``. With ``out`` the finished chunks go to its parts folder first (resume)
    and the rows to ``out`` at the end, holding ``out``'s lock (``bench.jobs.sweep_lock``)
    throughout. ``on_rows(done, total)`` is called after each chunk (benchmarks, tests)."""
    start = time.perf_counter()
    executor = executor.check()
    if chunk is not None:
        check_chunk_size(chunk)
    with sweep_lock(out) if out is not None else contextlib.nullcontext():
        return _run(plan, maneuvers, spec, out, executor, chunk, progress, on_rows, start)


def _run(plan: pd.DataFrame, maneuvers: Sequence[str], spec: Mapping[str, Any],
         out: Path | None, executor: Executor, chunk: int | None, progress: bool,
         on_rows: Callable[[int, int], None] | None, start: float) -> SweepResult:
    """:func:`run_sweep` once the options are checked and the lock is held."""
    samples, seed = int(spec.get("samples", 1)), int(spec.get("seed", 0))
    say = Console(stderr=True, soft_wrap=True, highlight=False).print
    parts = Parts.open(out, spec) if out is not None else None
    for line in parts.drop_damaged() if parts is not None else []:
        say(line)
    done = parts.done_ids() if parts is not None else set()
    todo = plan.loc[~plan["design_id"].isin(list(done))]
    resumed = len(plan) - len(todo)
    if parts is not None and resumed:
        say(f"resumed: {resumed} of {len(plan)} done ({parts.folder})")
    rows: list[dict[str, Any]] = []
    size = 0
    try:
        with opened(executor if len(todo) else Executor(), say) as runner:
            size = chunk_size(len(plan), runner.slots, chunk)
            if samples > 1:
                check_fits(todo, size, samples, *runner.memory())
            chunks = split(todo, maneuvers, size, samples, seed)
            with _bar(progress, len(plan), resumed) as advance:
                for flown in runner.results(chunks):
                    if parts is not None:
                        parts.write(flown)
                    else:
                        rows += flown
                    advance(len(flown))
                    if on_rows is not None:
                        on_rows(resumed + advance.completed, len(plan))
    except (KeyboardInterrupt, SweepLost, OutputLost):
        _say_kept(parts, len(plan), say)
        raise
    table = parts.table() if parts is not None else table_of(rows, maneuvers, samples)
    table = in_plan_order(table, plan["design_id"])
    if parts is not None and out is not None:
        try:
            write_atomic(table, out, spec)
        except OutputLost:
            _say_kept(parts, len(plan), say)
            raise
        parts.remove()
    return SweepResult(table, time.perf_counter() - start, resumed, len(todo), size)


def _say_kept(parts: Parts | None, total: int, say: Callable[[str], None]) -> None:
    """The line an interrupted sweep ends with: what its parts keep for the next run."""
    if parts is not None and parts.files():
        say(f"kept {len(parts.done_ids())} of {total} designs in {parts.folder}; run the "
            "same command again to fly the rest")


# ------------------------------------------------------------------ progress
class _Rate(ProgressColumn):
    """Designs per second over the last half minute (rich's own speed estimate)."""

    def render(self, task: Task) -> Text:
        speed = task.finished_speed or task.speed
        return Text("" if speed is None else f"{speed:.1f} designs/s", style="cyan")


class _Advance:
    """Counts designs flown by this run and moves the bar (if any)."""

    def __init__(self, bar: Progress | None, task: Any) -> None:
        self.bar, self.task, self.completed = bar, task, 0

    def __call__(self, n: int) -> None:
        self.completed += n
        if self.bar is not None:
            self.bar.advance(self.task, n)


@contextlib.contextmanager
def _bar(show: bool, total: int, resumed: int) -> Iterator[_Advance]:
    """A progress bar on stderr from ``resumed`` to ``total`` designs (none if not
    ``show``); the rate and the time left count this run's designs only (rich estimates
    both from the advances, not from the start)."""
    if not show:
        yield _Advance(None, None)
        return
    with Progress(TextColumn("flying designs"), BarColumn(), MofNCompleteColumn(), _Rate(),
                  TimeRemainingColumn(), console=Console(stderr=True), transient=True) as bar:
        task = bar.add_task("sweep", total=total, completed=resumed)
        yield _Advance(bar, task)


# ------------------------------------------------------------------ executors
class _InProcess:
    """Chunks flown one after the other in this process."""

    slots = 1

    def memory(self) -> tuple[int | None, str]:
        """The bytes a chunk may take here, and whose they are."""
        return available_memory(), "on this machine"

    def results(self, chunks: Sequence[Chunk]) -> Iterator[list[dict[str, Any]]]:
        for chunk in chunks:
            yield fly_chunk(chunk)


class _Dask:
    """Chunks flown on a Dask cluster, results as they finish."""

    def __init__(self, client: Any, distributed: Any) -> None:
        self.client, self.distributed = client, distributed
        self.slots = max(1, sum(client.nthreads().values()))
        self.where = client.scheduler.address

    def memory(self) -> tuple[int | None, str]:
        """The bytes a chunk may take on the smallest worker: its memory limit, or its
        machine's available memory where it has none, over its threads (None: no worker
        yet)."""
        workers = self.client.scheduler_info(n_workers=-1).get("workers", {})
        if not workers:
            return None, "a worker"
        try:
            machines = self.client.run(available_memory)
        except (ModuleNotFoundError, OSError, TimeoutError):  # results() says why, later
            machines = {}
        shares = [int(w.get("memory_limit") or machines.get(a) or 0)
                  // max(1, int(w.get("nthreads") or 1)) for a, w in workers.items()]
        return (min(shares) or None), "per worker thread of the cluster"

    def results(self, chunks: Sequence[Chunk]) -> Iterator[list[dict[str, Any]]]:
        d = self.distributed
        token = uuid.uuid4().hex[:12]
        waiting = iter(enumerate(chunks))
        limit = max(MIN_IN_FLIGHT, IN_FLIGHT_PER_SLOT * self.slots)

        def submit() -> Any:
            nxt = next(waiting, None)
            if nxt is None:
                return None
            i, chunk = nxt
            return self.client.submit(fly_chunk, chunk, key=f"rotorbench-fly-{token}-{i}",
                                      pure=False)

        first = [f for f in (submit() for _ in range(min(limit, len(chunks)))) if f]
        pending = d.as_completed(first, loop=self.client.loop)
        try:
            for future in pending:
                rows = future.result()
                future.release()
                nxt = submit()
                if nxt is not None:
                    pending.add(nxt)
                yield rows
        except d.KilledWorker:
            raise SweepLost("a chunk of designs killed every worker that flew it (out of "
                            "memory, or a crash)") from None
        except (OSError, TimeoutError, d.client.FutureCancelledError) as exc:
            raise SweepLost(f"lost the Dask scheduler {self.where} ({type(exc).__name__})"
                            ) from None
        except ModuleNotFoundError as exc:
            raise SweepLost(f"a worker of {self.where} cannot import the sweep code ({exc}): "
                            "install rotorbench, the same version, where the workers "
                            "run") from None


def _distributed() -> Any:
    """``distributed``, or a one-line refusal naming the extra to install (exit 2)."""
    try:
        import distributed
    except ImportError:
        raise RequestError(f"--workers/--scheduler need Dask's distributed scheduler: "
                           f"{EXTRA}") from None
    return distributed


@contextlib.contextmanager
def opened(executor: Executor, say: Callable[[str], None]) -> Iterator[Any]:
    """The executor's runner (``slots``: worker threads; ``results(chunks)``: each
    chunk's rows as it finishes; a Dask runner's ``client``), the cluster started or
    reached, and closed at the end."""
    if executor.in_process:
        yield _InProcess()
        return
    d = _distributed()
    with contextlib.ExitStack() as stack:
        stack.enter_context(_quiet("distributed"))
        if executor.scheduler is not None:
            client = stack.enter_context(_connect(d, executor.scheduler))
            what = f"Dask scheduler {executor.scheduler}"
        else:
            bokeh = importlib.util.find_spec("bokeh") is not None
            # the scheduler's HTTP server on a free port: the default (8787) is taken by
            # any other cluster on the machine, which distributed warns about
            with _unprofiled(not bokeh):
                cluster = stack.enter_context(d.LocalCluster(
                    n_workers=executor.workers, threads_per_worker=1, processes=True,
                    host="127.0.0.1", dashboard_address="127.0.0.1:0" if bokeh else None,
                    scheduler_kwargs={} if bokeh else {"dashboard_address": "127.0.0.1:0"},
                    silence_logs=logging.CRITICAL, preload=["bench.jobs.sweep_worker"]))
            client = stack.enter_context(d.Client(cluster, set_as_default=False))
            what = f"Dask LocalCluster of {executor.workers} worker processes"
        runner = _Dask(client, d)
        say(f"{what}: {runner.slots} worker threads" + _dashboard(client, executor))
        if executor.scheduler is not None and not client.nthreads():
            say("no workers on the cluster yet: the chunks wait for them")
        yield runner


@contextlib.contextmanager
def _unprofiled(off: bool) -> Iterator[None]:
    """With ``off``, the LocalCluster's workers start without their statistical profiler.
    Without a dashboard nobody reads its profiles, while it samples the flying thread's
    stack every 10 ms (about a tenth of a worker's CPU in a sweep). Each worker takes the
    configuration its nanny was made with, so the setting needs to hold only while the
    cluster starts."""
    if not off:
        yield
        return
    import dask.config

    with dask.config.set({"distributed.worker.profile.enabled": False}):
        yield


def _dashboard(client: Any, executor: Executor) -> str:
    """``, dashboard URL`` where there is one: a LocalCluster's with bokeh installed, a
    remote scheduler's when its status page answers (its HTTP server runs without the
    dashboard too)."""
    if "dashboard" not in client.scheduler_info().get("services", {}):
        return ""
    link = client.dashboard_link
    if executor.scheduler is None:
        return f", dashboard {link}" if importlib.util.find_spec("bokeh") else ""
    import urllib.request

    try:
        with urllib.request.urlopen(link, timeout=2.0) as page:
            return f", dashboard {link}" if page.status == 200 else ""
    except OSError:
        return ""


@contextlib.contextmanager
def _quiet(name: str) -> Iterator[None]:
    """Logger ``name`` and its children silent but for critical records: the sweep
    reports a lost scheduler itself, in one line, instead of the client's tracebacks."""
    names = [n for n in list(logging.root.manager.loggerDict)
             if n == name or n.startswith(name + ".")]
    loggers = [logging.getLogger(n) for n in dict.fromkeys([name, *names])]
    levels = [log.level for log in loggers]
    for log in loggers:
        log.setLevel(logging.CRITICAL)
    try:
        yield
    finally:
        for log, level in zip(loggers, levels, strict=True):
            log.setLevel(level)


@contextlib.contextmanager
def _connect(d: Any, address: str) -> Iterator[Any]:
    """A client of the scheduler at ``address``; unreachable, or something else there
    (``bench.jobs.sweep_scheduler``), is one line, exit 2."""
    probe(address, CONNECT_TIMEOUT_S)
    try:
        client = d.Client(address, timeout=f"{CONNECT_TIMEOUT_S:g}s", set_as_default=False)
    except (OSError, TimeoutError, ValueError, TypeError) as exc:
        text = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise RequestError(f"--scheduler {address}: cannot reach a Dask scheduler there "
                           f"({text})") from None
    with client:
        yield client
