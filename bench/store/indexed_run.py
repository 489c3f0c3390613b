"""A run folder that is in the run index from its start to its end, whatever happens.

Both sessions (bench runs and calibration stages) create a recorder, index the run as
``running``, hand the recorder to a runner and, whatever happened, make sure the run is
finished (``fail`` if the runner never got to it) and its final status indexed. A run
ended by Ctrl-C or by a failed write (disk full) comes out as an exception that says
where the run is recorded and with which status.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Any

from bench.engine.recorder import BASE_COLUMNS, RunRecorder, new_run_id
from bench.errors import RecordingError, RigError
from bench.store.run_index import RunIndex

__all__ = ["RunInterrupted", "RunRecordingFailed", "indexed_run"]


def _safe_stop_words(meta: Mapping[str, Any], safe: str) -> str:
    """``safe`` (what the safe stop did), or the errors the safe stop reported."""
    errors = [str(e) for e in meta.get("safe_stop_errors") or []]
    return f"safe stop reported: {'; '.join(errors)}" if errors else safe


class RunInterrupted(KeyboardInterrupt):
    """Ctrl-C or SIGTERM ended a recorded run: where it is recorded and with which status.

    Still a ``KeyboardInterrupt`` (the CLI exits 130); the commands print ``summary``
    first so the operator learns where the run went.
    """

    def __init__(self, run_dir: Path, meta: Mapping[str, Any], cause: BaseException) -> None:
        super().__init__(*cause.args)
        self.run_dir = run_dir
        self.meta = dict(meta)
        self.status = str(meta.get("status", "unknown"))
        self.reason = str(meta.get("reason", ""))
        self.how = "SIGTERM" if "SIGTERM" in cause.args else "Ctrl-C"

    def summary(self, what: str, safe: str) -> str:
        """One line: ``<what> aborted by operator (Ctrl-C): <safe>; recorded in <dir>
        (status abort)``; ``safe`` is replaced by the safe stop's errors if it had any."""
        return (f"{what} aborted by operator ({self.how}): {_safe_stop_words(self.meta, safe)}; "
                f"recorded in {self.run_dir} (status {self.status})")


class RunRecordingFailed(RecordingError):
    """A write to the run folder failed mid-run (disk full): the run was aborted, the
    actuators made safe, and what reached the disk stays readable. Exit code 2; the
    message says where the partial run is (``summary`` with the bench's own words)."""

    def __init__(self, run_dir: Path, meta: Mapping[str, Any], cause: RecordingError) -> None:
        self.run_dir = run_dir
        self.meta = dict(meta)
        self.cause = str(cause)
        super().__init__(self.summary("run", "actuators made safe"))

    def summary(self, what: str, safe: str) -> str:
        """``<what> aborted: <cause>; <safe>; the partial run is in <dir> (status abort,
        N rows readable)``."""
        rows = self.meta.get("rows", 0)
        return (f"{what} aborted: {self.cause}; {_safe_stop_words(self.meta, safe)}; the "
                f"partial run is in {self.run_dir} (status {self.meta.get('status', 'unknown')}, "
                f"{rows} rows readable)")


@contextlib.contextmanager
def indexed_run(out_root: Path, name: str, meta: Mapping[str, Any], *,
                base_columns: tuple[str, ...] = BASE_COLUMNS) -> Iterator[RunRecorder]:
    """A new run folder ``out_root/<id>`` recording ``meta``, indexed on entry and on exit."""
    out_root = Path(out_root)
    index = RunIndex(out_root)
    run_dir = out_root / new_run_id(name)
    recorder = RunRecorder(run_dir, meta, base_columns=base_columns)
    index.upsert(recorder.meta, run_dir)
    interrupted: KeyboardInterrupt | None = None
    failed: RecordingError | None = None
    try:
        yield recorder
    except KeyboardInterrupt as exc:  # re-raised below, once the record is complete
        interrupted = exc
    except RecordingError as exc:
        failed = exc
    finally:
        if not recorder.closed:  # the runner could not even be built
            recorder.finish("fail", "runner did not start")
        try:
            index.upsert(recorder.meta, run_dir)
        except RigError:
            if failed is None:  # a full disk may refuse the index too: run.json says it
                raise
    if interrupted is not None:
        raise RunInterrupted(run_dir, recorder.meta, interrupted) from interrupted
    if failed is not None:
        raise RunRecordingFailed(run_dir, recorder.meta, failed) from None
