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

__all__ = ["indexed_run"]


@contextlib.contextmanager
def indexed_run(out_root: Path, name: str, meta: Mapping[str, Any], *,
                base_columns: tuple[str, ...] = BASE_COLUMNS) -> Iterator[RunRecorder]:
    """A new run folder ``out_root/<id>`` recording ``meta``, indexed on entry and on exit."""
    out_root = Path(out_root)
    index = RunIndex(out_root)
    run_dir = out_root / new_run_id(name)
    recorder = RunRecorder(run_dir, meta, base_columns=base_columns)
    index.upsert(recorder.meta, run_dir)
    try:
        yield recorder
    finally:
        if not recorder.closed:  # the runner could not even be built
            recorder.finish("fail", "runner did not start")
        index.upsert(recorder.meta, run_dir)
