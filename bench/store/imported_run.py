"""Another logger's samples as a run folder: written aside, renamed into place whole.

``rotorbench import`` (a thrust stand's or a flight controller's log) and the Betaflight
flight of ``rotorbench fly`` (the firmware's own blackbox log) both land here: the
samples go through ``bench.engine.recorder.RunRecorder`` into a temporary folder beside
the run's and are renamed into place, so an interrupted write leaves nothing
half-written under the final name.
"""

from __future__ import annotations

import itertools
import shutil
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from bench.errors import RigError

__all__ = ["write_run"]


def write_run(out: Path, samples, meta: dict) -> Path:
    """Write ``samples`` (a DataFrame with run columns) and ``meta`` as a run folder; the
    run's reason names the log (``meta["import"]["source_file"]``)."""
    from bench.engine.recorder import BASE_COLUMNS, RunRecorder

    out = Path(out)
    if out.exists():
        raise RigError(f"--out {out}: already exists (choose a new run folder)")
    tmp = out.with_name(f".{out.name}.importing")
    if tmp.exists():
        shutil.rmtree(tmp)
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise RigError(f"--out {out}: cannot create its folder {out.parent} "
                       f"({exc.strerror or exc})") from None
    n = len(samples)
    cols = {c: samples[c].to_numpy(dtype=float) for c in samples.columns}
    for c in BASE_COLUMNS:  # the recorder's schema: absent channels are NaN
        cols.setdefault(c, np.full(n, np.nan))
    try:
        rec = RunRecorder(tmp, {"id": out.name, **meta})
        # append in slices so the recorder writes its usual <= 1 s parts
        t = cols["t_s"]
        # a cut where the whole second since the start changes: O(rows), whatever the gaps
        cuts = np.flatnonzero(np.diff(np.floor(t - t[0]))) + 1
        bounds = [0, *cuts.tolist(), n]
        for a, b in itertools.pairwise(bounds):
            if b > a:
                rec.append({c: v[a:b] for c, v in cols.items()})
        rec.finish("success", f"imported from {meta['import']['source_file']}",
                   duration_s=float(t[-1] - t[0]))
        tmp.rename(out)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return out


def store_flight_log(log: Path, root: Path, name: str, extra: dict,
                     augment: Callable[[Any], None] | None = None) -> Path:
    """A blackbox log as an indexed run of kind ``flight`` under ``root`` (the one log of
    one arming; a file of several keeps the last), the log file itself kept beside its
    samples. ``extra`` goes into run.json (what flew it); ``augment`` may add columns to
    the decoded ``FlightLog`` first (what the bench knows and the log lacks)."""
    import pandas as pd

    from analysis.flightlogs import read_flight_log
    from analysis.run_paths import read_run_json
    from bench.engine.recorder import new_run_id
    from bench.store.run_index import RunIndex

    logs = read_flight_log(log, "blackbox")
    if not logs:
        raise RigError(f"{log}: the firmware's log holds no flight")
    flight = logs[-1]
    if augment is not None:
        augment(flight)
    source = {"source_file": log.name, "format": "blackbox", "format_taken": "written by "
              "the firmware", "log_in_file": len(logs), "logs_in_file": len(logs)}
    meta = {"kind": "flight", "components": {}, "import": source, "flight": flight.run_meta(),
            **extra}
    run_dir = write_run(Path(root) / new_run_id(name), pd.DataFrame(flight.columns, copy=False),
                        meta)
    shutil.copyfile(log, run_dir / log.name)
    RunIndex(Path(root)).upsert(read_run_json(run_dir), run_dir)
    return run_dir
