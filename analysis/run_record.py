"""Read a run folder (``run.json``, samples, events) without importing ``bench``.

The folder format is the one ``bench.engine.recorder`` writes (DESIGN.md "Run records"):
``run.json`` with the metadata, the samples as one Parquet file or a folder of Parquet
parts (hidden temporary names are skipped, so a crashed run stays readable) and an
``events.csv`` table. Analysis reads logs from any source through this one function, so
an imported log and a bench run look the same to every fit.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from analysis.errors import LogError
from analysis.run_paths import (
    SAMPLES_DEFAULT,
    events_path,
    files_under,
    read_run_json,
    samples_path,
)

__all__ = ["ColumnChunks", "RunRecord", "esc_frame_s", "event_times", "events_path",
           "read_columns", "read_meta", "read_run", "sample_count", "samples_path"]


@dataclass(frozen=True)
class RunRecord:
    """One run: where it is, its metadata, its samples (sorted by ``t_s``) and events."""

    path: Path
    meta: dict[str, Any]
    samples: pd.DataFrame
    events: pd.DataFrame = field(default_factory=pd.DataFrame)

    @property
    def id(self) -> str:
        return str(self.meta.get("id") or self.path.name)

    @property
    def components(self) -> dict[str, Any]:
        comp = self.meta.get("components")
        return dict(comp) if isinstance(comp, dict) else {}

    def thrust_zeroed(self) -> bool:
        """Whether the run's thrust reads from zero: the bench's propulsion runs do, and
        keep ``tare`` (each channel the run zeroed, empty where none: the cell reads from
        its board's zero; runs recorded before kept the thrust's offset alone, as
        ``tare_offset_n``); an imported log need not."""
        return "tare" in self.meta or "tare_offset_n" in self.meta

    def column(self, name: str) -> np.ndarray:
        """A sample column as float array; ``LogError`` naming the file if missing."""
        if name not in self.samples.columns:
            raise LogError(f"{self.path / _samples_name(self.meta)}: no column {name!r} "
                           f"(columns: {', '.join(map(str, self.samples.columns))})")
        return self.samples[name].to_numpy(dtype=float)


def _samples_name(meta: dict[str, Any]) -> str:
    name = meta.get("samples") or SAMPLES_DEFAULT
    return name if isinstance(name, str) else SAMPLES_DEFAULT


def read_run(path: str | Path) -> RunRecord:
    """Load a run folder; every problem raises ``LogError`` naming the file and the fault."""
    run_dir = Path(path)
    meta = read_meta(run_dir)
    samples = _read_samples(run_dir, samples_path(run_dir, meta))
    events = _read_events(events_path(run_dir, meta))
    return RunRecord(run_dir, meta, samples, events)


def read_meta(run_dir: str | Path) -> dict[str, Any]:
    """Only a run folder's ``run.json`` (a page that shows the metadata needs no samples);
    ``analysis.run_paths.read_run_json``, re-exported where the rest of a run is read."""
    return read_run_json(run_dir)


def sample_count(run_dir: str | Path, meta: dict[str, Any] | None = None) -> int:
    """Rows of a run's samples from the Parquet footers, without reading the data."""
    import pyarrow.dataset as ds

    run_dir = Path(run_dir)
    path = samples_path(run_dir, meta if meta is not None else read_meta(run_dir))
    parts = _sample_parts(run_dir, path, empty=True)
    if not parts:
        return 0
    try:
        return int(ds.dataset([str(p) for p in parts], format="parquet",
                              exclude_invalid_files=True).count_rows())
    except Exception as exc:  # pyarrow raises several types for damaged files
        raise LogError(_not_parquet(path, exc)) from None


def read_columns(run_dir: str | Path, columns: list[str]) -> dict[str, np.ndarray]:
    """Some sample columns of a run as float arrays sorted by ``t_s`` (which is always
    read): a long run's plots need a few columns, not the whole table. Columns the run
    lacks are left out; the same checks as ``read_run`` on ``t_s``."""
    chunks = ColumnChunks(run_dir, columns)
    parts = list(chunks)
    return {"t_s": chunks.t} | {name: np.concatenate([c[name] for c in parts])
                                for name in chunks.names}


class ColumnChunks:
    """Some sample columns of a run, a chunk of rows at a time in ``t_s`` order.

    ``t`` (all of ``t_s``, checked as ``read_run`` checks it) is read at once; iterating
    gives ``{column: float array}`` for consecutive rows (``rows`` at most), so a 5 M-row
    run's plots are reduced from a few MB at a time, not from whole 40 MB columns (whose
    fresh pages cost the kernel more than the reduction costs: 3.8x the wall time of a
    first read, benchmarks/serve_series_read.py). The parts are read one after the other
    in this thread: pyarrow's dataset scanner was no faster, and with its threads slower
    and less even on a busy 2-core machine. ``names``: the asked columns the run has
    (from its first part; a part without one gives NaN). A log whose clock stepped back
    comes in one chunk, sorted."""

    def __init__(self, run_dir: str | Path, columns: list[str], rows: int = 131_072) -> None:
        import pyarrow.parquet as pq

        run_dir = Path(run_dir)
        self.path = path = samples_path(run_dir, read_meta(run_dir))
        self.rows = rows
        self._files = _sample_parts(run_dir, path)
        try:
            have = pq.read_schema(self._files[0]).names
        except Exception as exc:  # pyarrow raises several types for damaged files
            raise LogError(_not_parquet(path, exc)) from None
        if "t_s" not in have:
            raise LogError(f"{path}: no 't_s' column")
        self.names = [c for c in dict.fromkeys(columns) if c in have and c != "t_s"]
        t = np.concatenate([c["t_s"] for c in self._read(["t_s"], None)])
        if t.size == 0:
            raise LogError(f"{path}: no samples")
        self._order = _time_order(t, path)
        self.t = t if self._order is None else t[self._order]

    def __iter__(self) -> Iterator[dict[str, np.ndarray]]:
        if not self.names:
            return
        if self._order is None:
            yield from self._read(self.names, self.rows)
            return
        parts = list(self._read(self.names, None))
        yield {c: np.concatenate([p[c] for p in parts])[self._order] for c in self.names}

    def _read(self, names: list[str], rows: int | None) -> Iterator[dict[str, np.ndarray]]:
        """Each part's ``names`` in batches of ``rows`` (None: the part at once)."""
        import pyarrow.parquet as pq

        try:
            for f in self._files:
                with pq.ParquetFile(f, pre_buffer=False) as part:
                    there = [c for c in names if c in part.schema_arrow.names]
                    if not there:  # a part written before these columns existed
                        yield {c: np.full(part.metadata.num_rows, np.nan) for c in names}
                        continue
                    for batch in (part.iter_batches(rows, columns=there, use_threads=False)
                                  if rows else [part.read(there, use_threads=False)]):
                        yield {c: _floats(batch.column(c)) if c in there
                               else np.full(batch.num_rows, np.nan) for c in names}
        except Exception as exc:  # pyarrow raises several types for damaged files
            raise LogError(_not_parquet(self.path, exc)) from None


def _not_parquet(path: Path, exc: BaseException) -> str:
    """The one-line fault of an unreadable Parquet file or folder. Only the exception's
    type is named: pyarrow's and pandas' texts may carry bytes of the file."""
    return (f"{path}: not readable as Parquet (not a Parquet file, or a damaged one: "
            f"{type(exc).__name__})")


def _floats(column: Any) -> np.ndarray:
    """A pyarrow column as a float array (nulls as NaN)."""
    return np.asarray(column.to_numpy(zero_copy_only=False), dtype=float)


def _sample_parts(run_dir: Path, path: Path, *, empty: bool = False) -> list[Path]:
    """The samples file, or the parts of the samples folder (hidden temporary parts left
    out); every file in the folder checked to stay inside the run folder. A folder
    without parts is a ``LogError`` unless ``empty`` (a run that has not written one)."""
    if not path.exists():
        raise LogError(f"{path}: missing (the run's samples)")
    if path.is_file():
        return [path]
    if not path.is_dir():  # a FIFO or device: would block or read without end
        raise LogError(f"{path}: not a regular file or folder")
    parts = [p for p in files_under(run_dir, path) if p.parent == path
             and p.suffix == ".parquet" and not p.name.startswith((".", "_"))]
    if not parts and not empty:
        raise LogError(f"{path}: no sample parts in the folder (the run recorded nothing)")
    return parts


def _read_samples(run_dir: Path, path: Path) -> pd.DataFrame:
    parts = _sample_parts(run_dir, path)
    try:  # the parts listed, not the folder: pyarrow would walk its sub-folders and links
        # pandas annotates one path, but hands a list of part files to pyarrow as it is
        df = pd.read_parquet([str(p) for p in parts] if path.is_dir() else path)  # pyright: ignore[reportArgumentType]
    except Exception as exc:  # pyarrow raises several types for damaged files
        raise LogError(_not_parquet(path, exc)) from None
    if "t_s" not in df.columns:
        raise LogError(f"{path}: no 't_s' column (columns: {', '.join(map(str, df.columns))})")
    if len(df) == 0:
        raise LogError(f"{path}: no samples")
    for name in df.columns:
        if not pd.api.types.is_numeric_dtype(df[name]):
            raise LogError(f"{path}: column {name!r} is not numeric ({df[name].dtype})")
    if _time_order(df["t_s"].to_numpy(dtype=float), path) is not None:
        df = df.sort_values("t_s", kind="stable")
    return df.reset_index(drop=True)


def _time_order(t: np.ndarray, path: Path) -> np.ndarray | None:
    """Check ``t_s`` (every value finite) and return the order that sorts it, or None
    when it is sorted already (a log whose clock stepped back is sorted, stably)."""
    if not np.all(np.isfinite(t)):
        bad = int(np.flatnonzero(~np.isfinite(t))[0])
        raise LogError(f"{path}: row {bad}: t_s is not a finite number")
    return np.argsort(t, kind="stable") if np.any(t[1:] < t[:-1]) else None


def _read_events(path: Path) -> pd.DataFrame:
    if not path.exists():
        return pd.DataFrame(columns=["t_s", "kind", "step", "label", "detail"])
    if not path.is_file():
        raise LogError(f"{path}: not a regular file")
    try:
        ev = pd.read_csv(path, dtype={"kind": str, "label": str, "detail": str},
                         keep_default_na=False, na_values={"t_s": [""], "step": [""]})
    except Exception as exc:  # the parser's text may quote the file: only its type
        raise LogError(f"{path}: not a readable events table (CSV: {type(exc).__name__})"
                       ) from None
    if "t_s" not in ev.columns or "kind" not in ev.columns:
        raise LogError(f"{path}: not an events table (its header has no columns t_s and "
                       "kind)")
    ev["t_s"] = pd.to_numeric(ev["t_s"], errors="coerce")
    return ev


def event_times(record: RunRecord, kind: str = "step_start") -> np.ndarray:
    """Times (s) of the events of one kind, sorted; empty if the run has none."""
    ev = record.events
    if ev.empty or "kind" not in ev.columns:
        return np.empty(0)
    t = ev.loc[ev["kind"] == kind, "t_s"].to_numpy(dtype=float)
    return np.sort(t[np.isfinite(t)])


def esc_frame_s(record: RunRecord) -> float:
    """The ESC input frame period from run.json (``rig.esc.frame_rate_hz``), or NaN."""
    rig = record.meta.get("rig")
    esc = rig.get("esc") if isinstance(rig, dict) else None
    value = esc.get("frame_rate_hz") if isinstance(esc, dict) else None
    if not isinstance(value, int | float | str):
        return math.nan
    try:
        rate = float(value)
    except (TypeError, ValueError):
        return math.nan
    return 1.0 / rate if rate > 0 else math.nan
