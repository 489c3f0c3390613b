"""Run folders: ``run.json``, ``samples.parquet/`` (a folder of parts) and ``events.csv``.

Samples are written as they arrive in parts of at most ``chunk_s`` seconds of data (one
second; ten for a simulated run written behind, ``RunRecorder.write_behind``). Each part
is written under a hidden temporary name and renamed into place, and
``pandas.read_parquet`` skips hidden names, so after a crash or ``kill -9`` every part
on disk is complete and readable: at most the last (unwritten) chunk is lost. The
columns are encoded losslessly and compactly (``part_encoding``).
``run.json`` is written at the start with status ``running`` and replaced atomically
at the end; events are appended one flushed line at a time.

A write that fails during the run (disk full, medium gone) raises ``RecordingError``: the
runner stops the actuators and ends the run as aborted. The parts already on disk stay
readable; the rows still buffered are dropped and counted (``rows_lost`` in ``run.json``),
and ``finish`` writes what it still can without raising again.
"""

from __future__ import annotations

import contextlib
import csv
import io
import json
import logging
import math
import os
import socket
import time
from collections.abc import Mapping
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from bench.engine import run_log
from bench.errors import RecordingError, RigError
from drivers.worker import Worker

__all__ = ["BASE_COLUMNS", "BEHIND_PART_S", "RunRecorder", "atomic_write_json", "new_run_id",
           "part_encoding", "software_version", "utc_now"]

BASE_COLUMNS = ("t_s", "throttle_us", "thrust_setpoint_n", "thrust_n", "current_a",
                "voltage_v", "rpm")
log = logging.getLogger(__name__)

SAMPLES_DIR = "samples.parquet"
EVENT_FIELDS = ("t_s", "utc", "kind", "step", "label", "detail")
BEHIND_PART_S = 10.0  # rig seconds per part of a simulated run written behind it


def utc_now() -> str:
    return datetime.now(UTC).isoformat(timespec="milliseconds")


def software_version() -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("rotorbench")
    except PackageNotFoundError:
        return "unknown"


def new_run_id(name: str) -> str:
    """``<UTC stamp>-<8 hex>-<name>``: sorts by start time, says what the run is, and stays
    unique across benches that start runs in the same microsecond (the hex digits are
    random bits of a UUIDv7, ``bench.engine.run_ids``)."""
    from bench.engine.run_ids import run_id_name, uuid7

    stamp = datetime.now(UTC).strftime("%Y%m%dT%H%M%S_%fZ")
    return f"{stamp}-{uuid7().hex[-8:]}-{run_id_name(name)}"


def operator() -> str:
    """Who runs the bench: ``$ROTORBENCH_OPERATOR``, else the login name. (The bench's
    name is ``--bench`` or ``$ROTORBENCH_BENCH``; the lab catalog falls back to the rig's.)"""
    import getpass

    name = os.environ.get("ROTORBENCH_OPERATOR")
    if name:
        return name
    try:
        return getpass.getuser()
    except (KeyError, OSError):  # no passwd entry (a container)
        return "unknown"


def atomic_write_json(path: Path, data: Mapping[str, Any],
                      cache: dict[str, tuple[Any, str]] | None = None) -> None:
    """Write JSON to a temporary file next to ``path`` and rename it into place.

    ``cache`` (kept by the caller between writes of the same file) holds the text of
    each top-level value that is a dict or list: written again unchanged (the same
    object), it is not converted again. ``run.json`` is written at the start and at the
    end of a run with the same plan and sequence, about 0.2 MB for a 200-repeat step,
    and the indented encoder is pure Python. The values must not be changed in place in
    between (the recorder's callers never do: they replace them)."""
    tmp = path.with_name(f".{path.name}.tmp")
    try:
        with open(tmp, "w", encoding="utf-8") as fh:
            fh.write(_json_text(data, cache))
            fh.write("\n")
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:  # a full disk leaves the old file, not half a new one beside it
        with contextlib.suppress(OSError):
            tmp.unlink(missing_ok=True)
        raise


def _json_text(data: Mapping[str, Any], cache: dict[str, tuple[Any, str]] | None) -> str:
    """``json.dumps(_jsonable(data), indent=2, allow_nan=False)``, built one top-level
    value at a time: a value nested one level down is its own indented text with two
    more spaces after every line break (strings never hold a raw one)."""
    if not data:
        return "{}"
    items = []
    for key, value in data.items():
        hit = cache.get(str(key)) if cache is not None else None
        if hit is not None and hit[0] is value:
            text = hit[1]
        else:
            text = json.dumps(_jsonable(value), indent=2, allow_nan=False).replace("\n", "\n  ")
            if cache is not None and isinstance(value, Mapping | list | tuple):
                cache[str(key)] = (value, text)
        items.append(f"  {json.dumps(str(key))}: {text}")
    return "{\n" + ",\n".join(items) + "\n}"


_PLAIN = frozenset((str, int, bool, type(None)))


def _jsonable(obj: Any) -> Any:
    kind = type(obj)  # the common exact types first: a 200-repeat plan has 12k values
    if kind is float:
        return obj if math.isfinite(obj) else None
    if kind in _PLAIN:
        return obj
    if kind is dict:
        return {str(k): _jsonable(v) for k, v in obj.items()}
    if isinstance(obj, Mapping):
        return {str(k): _jsonable(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [_jsonable(v) for v in obj]
    if isinstance(obj, np.generic):
        obj = obj.item()
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    if isinstance(obj, Path):
        return str(obj)
    if obj is None or isinstance(obj, str | int | float | bool):
        return obj
    return str(obj)


def _arrow(values: np.ndarray) -> pa.Array:
    """A numpy column as an Arrow array without copying. ``pa.array`` would import pandas
    (about 0.3 s of a command's start-up) to ask whether the column is a pandas object;
    numeric columns are wrapped as they are, anything else goes through ``pa.array``."""
    v = np.asarray(values)
    if v.dtype.kind in "iuf" and v.dtype.isnative and v.flags.c_contiguous:
        return pa.Array.from_buffers(pa.from_numpy_dtype(v.dtype), len(v),
                                     [None, pa.py_buffer(v)])
    return pa.array(v)


def part_encoding(cols: Mapping[str, np.ndarray]) -> dict[str, Any]:
    """How a part's columns are encoded (``pyarrow.parquet.write_table`` options), all
    lossless: the values read back are the ones written, bit for bit.

    A device gives counts: an ADC's 16 or 24 bits, a counter's ticks, scaled to SI units
    as float64. A second of such a channel holds a few hundred to a few thousand distinct
    values, so a dictionary (each value once, then a 10-12 bit index per sample) holds it
    in a third of the plain bytes, where lz4 on plain float64 finds little to take. Which
    columns repeat their values is read off each part (``_repeats``); the others are
    written plain (a dictionary of distinct values would cost ten times the plain write).
    The time stamps, distinct and increasing, have their bytes split into streams
    (``BYTE_STREAM_SPLIT``: the sign, exponent and high mantissa bytes, which hardly
    change from row to row, in streams of their own), which lz4 shrinks to about half.
    A 200-repeat Step 1 is 41 MB instead of 88 MB, for the same encoding time
    (docs/lab.md, Speed); every Parquet reader reads any of these encodings."""
    dictionary = [name for name, values in cols.items()
                  if values.dtype.kind not in "iufb" or _repeats(values)]  # text: as pyarrow
    split = [name for name in ("t_s",) if name in cols and name not in dictionary
             and cols[name].dtype.kind == "f"]
    return {"use_dictionary": dictionary, "use_byte_stream_split": split}


def _repeats(values: np.ndarray, sample: int = 4096) -> bool:
    """Whether a column repeats its values: at most half of an evenly spaced sample of
    ``sample`` rows distinct (0.05 ms a column; the simulated rig's quantised channels
    have 36 % or fewer, distinct values 100 %)."""
    picked = values[::max(1, len(values) // sample)][:sample]
    return len(picked) > 1 and 2 * len(np.unique(picked)) <= len(picked)


def _table(cols: Mapping[str, np.ndarray], schema: pa.Schema | None = None) -> pa.Table:
    arrays = [_arrow(v) for v in cols.values()]
    if schema is None:
        return pa.Table.from_arrays(arrays, names=list(cols))
    return pa.Table.from_arrays(arrays, schema=schema)


class _PartFailed(Exception):
    """A part written in the background failed (see ``RunRecorder.write_behind``)."""

    def __init__(self, what: str, exc: OSError, rows: int) -> None:
        super().__init__(what)
        self.what, self.exc, self.rows = what, exc, rows


class RunRecorder:
    """Writes one run folder; ``append`` columns as they come, ``finish`` once at the end."""

    def __init__(self, run_dir: Path, meta: Mapping[str, Any], chunk_s: float = 1.0,
                 compression: str = "lz4", base_columns: tuple[str, ...] = BASE_COLUMNS) -> None:
        if not 0 < chunk_s <= 1.0:
            raise ValueError("chunk_s must be in (0, 1] s: a crash may lose at most one second")
        self.run_dir = Path(run_dir)
        self.chunk_s = chunk_s
        self.compression = compression
        self.base_columns = tuple(base_columns)  # required in every batch, written first
        self.meta: dict[str, Any] = dict(meta)
        # Rows wait in one preallocated array per column (grown by doubling, reused for
        # every part): no per-batch lists, no concatenation, one table per part.
        self._buf: dict[str, np.ndarray] = {}
        self._n = 0
        self._schema: pa.Schema | None = None
        self._columns: tuple[str, ...] | None = None
        self.parts = 0
        self.rows_written = 0
        self.closed = False
        self.failure: str | None = None  # the first write that failed, if any
        # write-behind (see ``write_behind``): the thread writing the parts, if any
        self._writer: Worker | None = None
        self._rows_failed = 0  # rows of a part whose background write failed
        self._json_cache: dict[str, tuple[Any, str]] = {}  # run.json's plan, sequence...
        # The first Parquet write initialises pyarrow's writer (~0.3 s); do it now, not
        # inside the command loop where it would look like a stalled host.
        warm = {"t_s": np.arange(4.0), "x": np.zeros(4)}  # (and its encodings' code)
        pq.write_table(_table(warm), io.BytesIO(), compression=compression,
                       **part_encoding(warm))
        self.meta.setdefault("id", self.run_dir.name)
        self.meta.update(status="running", reason="", started_utc=utc_now(), ended_utc=None,
                         software_version=software_version(), host=socket.gethostname(),
                         operator=self.meta.get("operator") or operator(),
                         bench=self.meta.get("bench") or os.environ.get("ROTORBENCH_BENCH"),
                         pid=os.getpid(), samples=SAMPLES_DIR, events="events.csv",
                         log=run_log.LOG_NAME)
        # the run's diagnostic log: the lines since its devices began to open, if a
        # capture was started then (bench.plan_runner.session), else from here
        self._log_capture = contextlib.ExitStack()
        self._log_capture.enter_context(run_log.capture())
        try:
            self.run_dir.mkdir(parents=True, exist_ok=False)
            run_log.attach(self.run_dir)
            log.info("run %s recording into %s", self.meta["id"], self.run_dir)
            (self.run_dir / SAMPLES_DIR).mkdir()
            atomic_write_json(self.run_dir / "run.json", self.meta, self._json_cache)
            self._events = open(self.run_dir / "events.csv", "w", newline="", encoding="utf-8")
            self._events_csv = csv.writer(self._events)
            self._events_csv.writerow(EVENT_FIELDS)
            self._events.flush()
        except OSError as exc:
            self._log_capture.close()
            raise RigError(f"{self.run_dir}: cannot create the run folder "
                           f"({exc.strerror or exc})") from None

    # -- samples ------------------------------------------------------------------------

    def append(self, columns: Mapping[str, np.ndarray]) -> None:
        """Buffer one batch of rows (same length per column, ``t_s`` increasing)."""
        t = columns["t_s"]
        n = len(t)
        if n == 0:
            return
        if self._columns is None:
            base = self.base_columns
            missing = [c for c in base if c not in columns]
            if missing:
                raise ValueError(f"samples need the columns {missing}")
            self._columns = (*base, *[c for c in columns if c not in base])
            self._buf = {c: np.empty(max(4 * n, 1024), np.asarray(columns[c]).dtype)
                         for c in self._columns}
        end = self._n + n
        if end > len(self._buf["t_s"]):
            size = max(end, 2 * len(self._buf["t_s"]))
            for c, old in self._buf.items():
                grown = np.empty(size, old.dtype)
                grown[:self._n] = old[:self._n]
                self._buf[c] = grown
        for c, buf in self._buf.items():
            # same_kind: a float batch never silently truncates into an integer column
            np.copyto(buf[self._n:end], columns[c], casting="same_kind")
        self._n = end
        tb = self._buf["t_s"]
        while self._n and tb[self._n - 1] - tb[0] >= self.chunk_s:
            self._flush_until(tb[0] + self.chunk_s)

    def write_behind(self, part_s: float = BEHIND_PART_S) -> None:
        """Write each part in a background thread while the run goes on (pyarrow lets go
        of the GIL while it encodes and compresses), one part at a time, each holding
        ``part_s`` seconds of rig time.

        For simulated rigs run flat out, where the Parquet writing was a sixth of the
        command's time. The price: a failed write (disk full) is noticed when the next
        part is handed over or at ``finish``, one part later, and a crash may lose the
        part in flight as well as the buffered rows: up to twice ``part_s`` of rig time,
        a fifth of a second of the host's time at 100x real time. Parts of ten seconds
        rather than one make a tenth of the files, and a lab store a tenth of the uploads
        (every S3 request costs milliseconds of CPU on both sides, whatever its size:
        docs/lab.md, Speed). A rig with hardware keeps writing in line, in parts of a
        second, so a full disk stops the motor at once and a crash loses at most a
        second."""
        if part_s <= 0:
            raise ValueError("part_s must be > 0")
        self._writer = Worker("run-recorder")
        self.chunk_s = float(part_s)

    def flush(self) -> None:
        """Write everything buffered (used at the end of a run)."""
        self._flush_until(math.inf)
        self._wait_writer()

    def _flush_until(self, t_cut: float) -> None:
        n = self._n
        if not n:
            return
        cut = int(np.searchsorted(self._buf["t_s"][:n], t_cut, side="left"))
        if cut == 0:  # a single sample at the cut; never loop forever
            cut = 1
        self._wait_writer()
        if self._writer is not None:
            # the part keeps the buffers it was cut from; the rest moves to new ones
            part = {c: v[:cut] for c, v in self._buf.items()}
            fresh = {c: np.empty_like(v) for c, v in self._buf.items()}
            for c, v in fresh.items():
                v[:n - cut] = self._buf[c][cut:n]
            self._buf = fresh
            self._n = n - cut
            self._writer.submit(self._write_part, part, True)
            return
        self._write_part({c: v[:cut] for c, v in self._buf.items()})
        for v in self._buf.values():  # the rest moves to the front (less than one batch)
            v[:n - cut] = v[cut:n].copy()
        self._n = n - cut

    def _wait_writer(self) -> None:
        """Wait for the part written in the background; raise its failure here."""
        if self._writer is None or not self._writer.pending:
            return
        try:
            self._writer.result()
        except _PartFailed as err:
            self._rows_failed += err.rows
            self._failed(err.what, err.exc)

    def _write_part(self, cols: Mapping[str, np.ndarray], behind: bool = False) -> None:
        if self._schema is None:
            table = _table(cols)
            self._schema = table.schema
        else:  # the buffers keep their dtypes, so every part has the first one's schema
            table = _table(cols, self._schema)
        name = f"part-{self.parts:06d}.parquet"
        final = self.run_dir / SAMPLES_DIR / name
        tmp = final.with_name(f".{name}.tmp")
        try:
            pq.write_table(table, tmp, compression=self.compression,
                           # pyarrow takes a list of columns here; its stubs say only bool
                           write_statistics=["t_s"],  # pyright: ignore[reportArgumentType]
                           **part_encoding(cols))
            os.replace(tmp, final)
        except OSError as exc:
            with contextlib.suppress(OSError):
                tmp.unlink(missing_ok=True)
            what = f"cannot write samples to {final.parent}"
            if behind:  # in the writer's thread: _wait_writer raises it in the run's
                raise _PartFailed(what, exc, table.num_rows) from None
            self._failed(what, exc)
        self.parts += 1
        self.rows_written += table.num_rows

    # -- events and end -------------------------------------------------------------------

    def event(self, t_s: float, kind: str, step: int | None = None, label: str = "",
              detail: Mapping[str, Any] | None = None) -> None:
        """Append one event line (flushed at once, so a crash keeps it)."""
        if self._events.closed:
            return
        try:
            self._events_csv.writerow([
                "" if t_s is None or math.isnan(t_s) else f"{t_s:.6f}", utc_now(), kind,
                "" if step is None else step, label,
                json.dumps(_jsonable(detail), allow_nan=False) if detail else "",
            ])
            self._events.flush()
        except OSError as exc:
            if self.failure is None:  # after a failure the end of the run writes what it can
                self._failed(f"cannot write events to {self._events.name}", exc)

    def _failed(self, what: str, exc: OSError) -> None:
        self.failure = f"{what} ({exc.strerror or exc})"
        raise RecordingError(self.failure) from None

    def finish(self, status: str, reason: str, **extra: Any) -> dict[str, Any]:
        """Flush the samples and rewrite ``run.json`` with the exit status; idempotent."""
        if self.closed:
            return self.meta
        try:
            if self.failure is None:
                self.flush()
        finally:
            self.closed = True
            try:
                self._end_record(status, reason, extra)
            finally:
                log.info("run %s recorded: %s: %s (%d rows in %d parts%s)", self.meta["id"],
                         self.meta["status"], self.meta["reason"], self.rows_written,
                         self.parts, f"; {self.failure}" if self.failure else "")
                run_log.detach()
                self._log_capture.close()
        return self.meta

    def _end_record(self, status: str, reason: str, extra: Mapping[str, Any]) -> None:
        """Close the events and write the final ``run.json`` (a failed recording: what the
        disk still takes)."""
        with contextlib.suppress(OSError):  # a full disk cannot take the last line
            self._events.close()
        self.meta.update(extra)
        self.meta.update(status=status, reason=reason, ended_utc=utc_now(),
                         rows=self.rows_written, parts=self.parts, finished_unix=time.time())
        if self.failure is not None:
            if self.meta["status"] == "success":  # the last flush failed
                self.meta.update(status="abort", reason=f"recording failed: {self.failure}")
            self.meta.update(recording_error=self.failure,
                             rows_lost=self._n + self._rows_failed)
            self._n = 0
            with contextlib.suppress(OSError):  # run.json may keep "running"
                atomic_write_json(self.run_dir / "run.json", self.meta, self._json_cache)
        else:
            atomic_write_json(self.run_dir / "run.json", self.meta, self._json_cache)
