"""Deliver recorded runs to the lab catalog, behind the run: upload, then index.

A bench records every run into a local folder store first (the spool). Publishing a run
copies its folder to the data location and upserts its catalog row; only then is a
``.published`` marker written beside it, naming the catalog's UUID. A run is delivered
once, to one catalog (``bench.store.spool_destinations``): a run with a marker is never
published again, whatever catalog asks. A run whose upload or index entry failed keeps
no marker and stays in the spool; ``store sync`` publishes what is waiting, and running
it twice adds nothing (the marker, the upsert by id and the same object keys).
"""

from __future__ import annotations

import json
import socket
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from bench.errors import RigError
from bench.store.lab_catalog import LabCatalog, run_from_meta
from bench.store.run_data import DataLocation

__all__ = ["MARKER", "Pending", "Publisher", "bench_name", "is_published", "operator_name",
           "pending_runs", "read_meta"]

MARKER = ".published"


def bench_name(meta: Mapping[str, Any]) -> str:
    """The run's bench: ``--bench``, else the rig file's name, else the host."""
    rig = meta.get("rig")
    rig_name = rig.get("name") if isinstance(rig, Mapping) else rig
    return str(meta.get("bench") or rig_name or meta.get("host") or socket.gethostname())


def operator_name(meta: Mapping[str, Any]) -> str:
    """The run's operator (the recorder writes it), else whoever publishes it."""
    from bench.engine.recorder import operator

    return str(meta.get("operator") or operator())


def read_meta(run_dir: Path) -> dict[str, Any]:
    """A run folder's run.json as an object, else one-line ``RigError`` naming the file and
    the fault, never its content (``analysis.run_paths.read_run_json``)."""
    from analysis.errors import LogError
    from analysis.run_paths import read_run_json

    try:
        return read_run_json(run_dir)
    except LogError as exc:
        raise RigError(f"unreadable: {exc}") from None


def _rows(run_dir: Path, meta: Mapping[str, Any]) -> int:
    """The recorder's count from run.json; else the parts' own (an imported or killed run:
    only then is the reader, and pandas with it, 0.2 s, imported)."""
    if isinstance(meta.get("rows"), int):
        return int(meta["rows"])
    from analysis.errors import LogError
    from analysis.run_record import sample_count

    try:
        return sample_count(run_dir, dict(meta))
    except LogError:  # no parts yet, damaged part: count what the catalog can say
        return 0


@dataclass(frozen=True)
class Publisher:
    """Publishes run folders into ``catalog`` (whose UUID is ``catalog_id``) + ``data``."""

    catalog: LabCatalog
    data: DataLocation
    catalog_id: str

    def publish(self, run_dir: Path, done: set[str] | None = None) -> str:
        """Upload and index one ended run (``done``: its files a ``TrailingUpload`` sent
        already); returns its data URI. Raises ``RigError``
        (``CatalogUnavailable``/``DataUnavailable`` when a server is away)."""
        run_dir = Path(run_dir)
        meta = read_meta(run_dir)
        run_id = str(meta.get("id") or run_dir.name)
        uri = self.data.upload(run_dir, run_id, done=done)
        self.catalog.upsert_run(run_from_meta(meta, data=uri, samples=_rows(run_dir, meta),
                                              bench=bench_name(meta),
                                              operator=operator_name(meta)))
        (run_dir / MARKER).write_text(json.dumps({"catalog": self.catalog_id, "data": uri}),
                                      encoding="utf-8")
        return uri

    def announce(self, meta: Mapping[str, Any], run_dir: Path) -> bool:
        """Index a run that just started (status running) so the lab sees it; a server
        that is away costs nothing here (False), the run goes on."""
        try:
            self.catalog.upsert_run(run_from_meta(meta, data=self.data.run_uri(
                str(meta.get("id") or run_dir.name)), samples=0, bench=bench_name(meta),
                operator=operator_name(meta)))
        except RigError:
            return False
        return True


def is_published(run_dir: Path) -> bool:
    """A marker is there: the run reached the one catalog it was going to."""
    return (Path(run_dir) / MARKER).is_file()


@dataclass(frozen=True)
class Pending:
    """A spooled run not yet delivered: its run.json, or why it cannot be read."""

    run_dir: Path
    meta: dict[str, Any] | None
    unreadable: str | None = None


def pending_runs(spool: Path) -> list[Pending]:
    """Ended runs in ``spool`` not yet delivered, oldest first, and the run folders whose
    run.json cannot be read (named, never skipped in silence). A delivered run's marker is
    looked at, not its run.json (a bench's spool keeps every run)."""
    out = []
    for meta_path in sorted(Path(spool).glob("*/run.json")):
        run_dir = meta_path.parent
        if is_published(run_dir):
            continue
        try:
            meta = read_meta(run_dir)
        except RigError as exc:
            out.append(Pending(run_dir, None, str(exc)))
            continue
        if meta.get("status") != "running":
            out.append(Pending(run_dir, meta))
    return out
