"""A sweep's files: finished chunks as Parquet parts, then one Parquet file, both atomic.

While a sweep runs, every finished chunk is written to ``SWEEP.parquet.parts/`` as its own
part (a temporary name, then a rename: a part is whole or absent, whatever kills the
process), next to ``spec.json``, the sweep's spec (``optimizer.sweep.spec``). Running the
same command again reads which designs the parts hold and flies only the others; a
command with other options finds a different spec and is refused, naming the difference.
At the end the parts become ``SWEEP.parquet`` (again written beside and renamed, the spec
in its key-value metadata) and the folder is removed.

A part damaged after it was written (cut short by a copy, a full disk under another
tool) is found when the sweep resumes: it is removed and its chunk flies again, said in
one line. A folder that stops taking writes mid-sweep (read-only, gone) ends the sweep
with :class:`OutputLost`, one line naming the folder (exit 2), the finished parts kept.
"""

from __future__ import annotations

import contextlib
import json
import os
import shutil
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any

import pyarrow as pa
import pyarrow.parquet as pq

from bench.errors import RigError
from bench.paths.outputs import check_writable
from optimizer.errors import RequestError
from optimizer.sweep.rows import columns
from optimizer.sweep.spec import METADATA_KEY, spec_difference

#: Arrow types of the value kinds of ``optimizer.sweep.rows``
ARROW_TYPES = {"str": pa.string(), "int": pa.int64(), "float": pa.float64(),
               "bool": pa.bool_()}
SPEC_FILE = "spec.json"
PART_PREFIX = "part-"
TMP_PREFIX = ".tmp-"


class OutputLost(RigError):
    """The output folder stopped taking writes mid-sweep: the parts written so far stay
    and the same command resumes once it is writable again. One line, exit 2."""


def schema(maneuvers: Sequence[str], samples: int = 1) -> pa.Schema:
    """The Arrow schema of a sweep's rows."""
    return pa.schema([(name, ARROW_TYPES[kind])
                      for name, kind in columns(maneuvers, samples)])


def table_of(rows: Sequence[Mapping[str, Any]], maneuvers: Sequence[str],
             samples: int = 1) -> pa.Table:
    """Rows (``optimizer.sweep.fly_rows``) as a table of the sweep's schema."""
    return pa.Table.from_pylist(list(rows), schema=schema(maneuvers, samples))


def parts_folder(out: Path) -> Path:
    """Where the parts of the sweep writing ``out`` live: ``<out>.parts`` beside it."""
    return out.with_name(out.name + ".parts")


def write_atomic(table: pa.Table, path: Path, spec: Mapping[str, Any] | None = None) -> Path:
    """Write ``table`` to ``path`` through a temporary file in the same folder and a
    rename, so ``path`` is the old file or the new one, never half of one. ``spec``
    goes into the file's key-value metadata."""
    if spec is not None:
        meta = dict(table.schema.metadata or {})
        meta[METADATA_KEY.encode()] = json.dumps(spec).encode()
        table = table.replace_schema_metadata(meta)
    tmp = path.with_name(f"{TMP_PREFIX}{os.getpid()}-{path.name}")
    try:
        with open(tmp, "wb") as fh:  # Python's OSError: errno and strerror, not Arrow's text
            pq.write_table(table, fh)
        os.replace(tmp, path)
    except OSError as exc:
        raise _lost(path.parent, exc) from None
    finally:
        with contextlib.suppress(OSError):
            tmp.unlink()
    return path


def _lost(folder: Path, exc: OSError) -> OutputLost:
    return OutputLost(f"cannot write in {folder} ({exc.strerror or exc}); the finished "
                      "chunks stay, run the same command again once it is writable")


class Parts:
    """The parts folder of one sweep (see the module doc); made with the first part."""

    def __init__(self, folder: Path, spec: Mapping[str, Any]) -> None:
        self.folder = folder
        self.schema = schema(spec["maneuvers"], int(spec.get("samples", 1)))
        self.spec = dict(spec)
        self.maneuvers = tuple(spec["maneuvers"])
        self.samples = int(spec.get("samples", 1))

    @classmethod
    def open(cls, out: Path, spec: Mapping[str, Any]) -> Parts:
        """The parts of ``out``'s sweep: those a run with the same spec left (temporary
        files of a killed write are removed), or none yet; another spec there is refused
        (``RequestError``, exit 2) naming the first difference."""
        folder = parts_folder(out)
        if folder.exists():
            try:
                old = json.loads((folder / SPEC_FILE).read_text())
            except (OSError, ValueError):
                raise RequestError(f"--out {out}: {folder} exists but holds no sweep's "
                                   f"{SPEC_FILE}; remove it or choose another --out") from None
            diff = spec_difference(old, spec)
            if diff is not None:
                raise RequestError(f"--out {out}: {folder} holds an unfinished sweep with "
                                   f"other options ({diff}); run that command again to "
                                   f"finish it, or remove {folder}")
            check_writable(folder, f"--out {out}", folder=True)
            for tmp in folder.glob(f"{TMP_PREFIX}*"):
                tmp.unlink()
        return cls(folder, spec)

    def drop_damaged(self) -> list[str]:
        """Remove every part that does not read back whole with the sweep's columns (its
        designs are then flown again); one line per part saying so."""
        said = []
        for path in self.files():
            try:
                pq.read_table(path, schema=self.schema)
            except (pa.ArrowException, ValueError) as exc:
                why = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
                path.unlink()
                said.append(f"damaged part {path} ({why}): its chunk flies again")
        return said

    def _make(self) -> None:
        """The folder and its spec.json (atomic), before the first part goes in."""
        if self.folder.exists():
            return
        try:
            self.folder.mkdir()
            tmp = self.folder / f"{TMP_PREFIX}{SPEC_FILE}"
            tmp.write_text(json.dumps(self.spec, indent=1))
            os.replace(tmp, self.folder / SPEC_FILE)
        except OSError as exc:
            raise _lost(self.folder.parent if not self.folder.exists() else self.folder,
                        exc) from None

    def files(self) -> list[Path]:
        if not self.folder.is_dir():
            return []
        return sorted(self.folder.glob(f"{PART_PREFIX}*.parquet"))

    def done_ids(self) -> set[str]:
        """The ids of every design a part holds."""
        done: set[str] = set()
        for path in self.files():
            done.update(pq.read_table(path, columns=["design_id"])["design_id"].to_pylist())
        return done

    def write(self, rows: Sequence[Mapping[str, Any]]) -> Path:
        """One finished chunk as a part (atomic)."""
        self._make()
        first = rows[0]["design_id"]
        path = self.folder / f"{PART_PREFIX}{first}-{len(rows)}.parquet"
        return write_atomic(table_of(rows, self.maneuvers, self.samples), path)

    def table(self) -> pa.Table:
        """Every row the parts hold."""
        tables = [pq.read_table(p, schema=self.schema) for p in self.files()]
        return pa.concat_tables(tables) if tables else table_of([], self.maneuvers, self.samples)

    def remove(self) -> None:
        shutil.rmtree(self.folder, ignore_errors=True)


def in_plan_order(table: pa.Table, plan_ids: Iterable[str]) -> pa.Table:
    """One row per planned design, in plan order (a design flown twice, e.g. by a task
    Dask ran again after a worker died, appears once)."""
    position: dict[str, int] = {}
    for i, d in enumerate(table["design_id"].to_pylist()):
        position.setdefault(d, i)
    ids = list(plan_ids)
    missing = [d for d in ids if d not in position]
    if missing:
        raise RuntimeError(f"{len(missing)} designs of the plan have no row (first: "
                           f"{missing[0]})")
    return table.take(pa.array([position[d] for d in ids], type=pa.int64()))
