"""Upload a run's sample parts while it records, so the run is in the lab store moments
after it ends ("uploaded behind the run").

The recorder writes each part under a hidden name and renames it into place, so a visible
``samples.parquet/part-*.parquet`` is whole and never changes: a thread polls the spool
for the runs this process is recording and sends their new parts. ``run.json`` and
``events.csv`` are left for the publish at the end (``run.json`` last, the seal). The
bench never waits for the network: an upload that fails stops the trailing quietly and
the end-of-run publish (or ``store sync``) does the rest. A pass is cheap, so it runs ten
times a second and the parts follow the run closely: a bench's spool keeps every run it
recorded, and the folders there before the trailing started, or seen ended, or recorded
by another process, are never read again; a running run's ``run.json`` (0.25 MB for a
200-repeat Step 1) is parsed again only once it was replaced. Each run is announced to
the catalog as it is first seen (status running), so the web view's live page lists it.

The thread is stopped and joined before the interpreter shuts down (``atexit``), whatever
ended the command (an error, a full disk, SIGTERM): pyarrow work still in flight on a
daemon thread while Python finalises crashed the process (SIGSEGV in
``FileSystem.from_uri``) after the run had been recorded.
"""

from __future__ import annotations

import atexit
import logging
import os
import threading
from collections.abc import Callable
from pathlib import Path
from typing import Any

from analysis.errors import LogError
from analysis.run_paths import read_run_json, samples_path
from bench.errors import RigError
from bench.store.run_data import DataLocation

log = logging.getLogger(__name__)

__all__ = ["TrailingUpload"]


def _main_alive() -> bool:
    """False once the main thread has ended (the interpreter is shutting down)."""
    return threading.main_thread().is_alive()


class TrailingUpload:
    """A daemon thread sending the finished parts of this process's running runs."""

    def __init__(self, spool: Path, data: DataLocation, period_s: float = 0.1, *,
                 announce: Callable[[dict[str, Any], Path], object] | None = None) -> None:
        self.spool = Path(spool)
        self.data = data
        self.announce = announce  # called once per run this process records, as it starts
        self.period_s = period_s
        self.done: dict[str, set[str]] = {}  # run folder name -> relative paths sent
        self.passed: set[str] = set()  # run folders not to read again
        self._read: dict[str, tuple[tuple[int, int], dict[str, Any]]] = {}  # run folder ->
        # (its run.json's mtime and size, its content): parsed again only when replaced
        self.failed: str | None = None
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._loop, name="rotorbench-trailing-upload",
                                        daemon=True)

    def start(self) -> TrailingUpload:
        """Trail the runs recorded from now on (the folders already there are passed)."""
        self.passed.update(p.name for p in self.spool.glob("*/"))
        self._thread.start()
        atexit.register(self.stop)
        return self

    def stop(self) -> dict[str, set[str]]:
        """Stop after the pass under way; the parts sent, per run folder."""
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join(60)
        atexit.unregister(self.stop)
        return self.done

    def _loop(self) -> None:
        while not self._stop.wait(self.period_s) and _main_alive():
            try:
                self.send_new()
            except (RigError, OSError) as exc:  # the store or the spool went away: the
                # publish at the end (or store sync) decides
                self.failed = str(exc)
                # (a data location holds no credentials: run_data refuses them)
                log.info("trailing upload stopped (the publish at the end decides): %s",
                         self.failed)
                return
            except RuntimeError:
                # the interpreter is shutting down (a SIGTERM ended the command): Python
                # stops its thread pools before the atexit hook that stops this thread
                # runs, and a pool refuses new uploads; store sync delivers the rest
                if _main_alive():
                    raise
                return

    def send_new(self) -> None:
        """One pass: new whole parts of the runs this process records."""
        for meta_path in self.spool.glob("*/run.json"):
            run_dir = meta_path.parent
            if run_dir.name in self.passed:
                continue
            meta = self._meta(meta_path)
            if meta is None:
                continue  # being replaced right now: the next pass reads it
            if meta.get("pid") != os.getpid() or meta.get("status") != "running":
                self.passed.add(run_dir.name)  # ended, or another process's
                continue
            if run_dir.name not in self.done and self.announce is not None:
                self.announce(meta, run_dir)
            try:
                parts = samples_path(run_dir, meta)
            except LogError:  # names a place outside its folder: never sent, sync says why
                self.passed.add(run_dir.name)
                continue
            sent = self.done.setdefault(run_dir.name, set())
            new = sorted(p.relative_to(run_dir).as_posix() for p in parts.glob("*.parquet")
                         if not p.name.startswith("."))
            new = [r for r in new if r not in sent]
            if new:
                self.data.put_files(run_dir, str(meta.get("id") or run_dir.name), new)
                sent.update(new)

    def _meta(self, meta_path: Path) -> dict[str, Any] | None:
        """The run.json at ``meta_path``, read again only once it was replaced (the
        recorder writes it at the start and at the end of the run)."""
        try:
            st = meta_path.stat()
            stamp = (st.st_mtime_ns, st.st_size)
            hit = self._read.get(meta_path.parent.name)
            if hit is not None and hit[0] == stamp:
                return hit[1]
            meta = read_run_json(meta_path.parent)
        except (OSError, LogError):
            return None
        self._read[meta_path.parent.name] = (stamp, meta)
        return meta
