"""A run folder that is in the run index from its start to its end, whatever happens.

Both sessions (bench runs and calibration stages) create a recorder, index the run as
``running``, hand the recorder to a runner and, whatever happened, make sure the run is
finished (``fail`` if the runner never got to it) and its final status indexed.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Any

from bench.recorder import BASE_COLUMNS, RunRecorder, new_run_id
from bench.run_index import RunIndex

__all__ = ["RunInterrupted", "indexed_run"]


class RunInterrupted(KeyboardInterrupt):
    """Ctrl-C or SIGTERM ended a recorded run: where it is recorded and with which status.

    Still a ``KeyboardInterrupt`` (the CLI exits 130); the commands print ``summary``
    first so the operator learns where the run went.
    """

    def __init__(self, run_dir: Path, meta: Mapping[str, Any], cause: BaseException) -> None:
        super().__init__(*cause.args)
        self.run_dir = run_dir
        self.status = str(meta.get("status", "unknown"))
        self.reason = str(meta.get("reason", ""))
        self.safe_stop_errors = [str(e) for e in meta.get("safe_stop_errors") or []]
        self.how = "SIGTERM" if "SIGTERM" in cause.args else "Ctrl-C"

    def summary(self, what: str, safe: str) -> str:
        """One line: ``<what> aborted by operator (Ctrl-C): <safe>; recorded in <dir>
        (status abort)``; ``safe`` is replaced by the safe stop's errors if it had any."""
        stop = (f"safe stop reported: {'; '.join(self.safe_stop_errors)}"
                if self.safe_stop_errors else safe)
        return (f"{what} aborted by operator ({self.how}): {stop}; recorded in {self.run_dir} "
                f"(status {self.status})")


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
    try:
        yield recorder
    except KeyboardInterrupt as exc:  # re-raised below, once the record is complete
        interrupted = exc
    finally:
        if not recorder.closed:  # the runner could not even be built
            recorder.finish("fail", "runner did not start")
        index.upsert(recorder.meta, run_dir)
    if interrupted is not None:
        raise RunInterrupted(run_dir, recorder.meta, interrupted) from interrupted
