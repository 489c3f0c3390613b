"""Deliver recorded runs to the lab catalog, behind the run: upload, then index.

A bench records every run into a local folder store first (the spool). Publishing a run
copies its folder to the data location and upserts its catalog row; only then is a
``.published`` marker written beside it. A run whose upload or index entry failed keeps
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
from bench.store.store_url import redact

__all__ = ["MARKER", "Publisher", "bench_name", "operator_name", "pending_runs"]

MARKER = ".published"


def bench_name(meta: Mapping[str, Any]) -> str:
    """The run's bench: ``--bench``, else the rig file's name, else the host."""
    rig = meta.get("rig")
    rig_name = rig.get("name") if isinstance(rig, Mapping) else rig
    return str(meta.get("bench") or rig_name or meta.get("host") or socket.gethostname())


def operator_name(meta: Mapping[str, Any]) -> str:
    """The run's operator (the recorder writes it), else whoever publishes it."""
    from bench.run.recorder import operator

    return str(meta.get("operator") or operator())


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
    """Publishes run folders of a spool into ``catalog`` + ``data``."""

    catalog: LabCatalog
    data: DataLocation

    def store_key(self) -> str:
        return redact(self.catalog.dsn)

    def is_published(self, run_dir: Path) -> bool:
        try:
            mark = json.loads((Path(run_dir) / MARKER).read_text(encoding="utf-8"))
        except (OSError, ValueError):
            return False
        return mark.get("store") == self.store_key()

    def publish(self, run_dir: Path, done: set[str] | None = None) -> str:
        """Upload and index one ended run (``done``: its files a ``TrailingUpload`` sent
        already); returns its data URI. Raises ``RigError``
        (``CatalogUnavailable``/``DataUnavailable`` when a server is away)."""
        run_dir = Path(run_dir)
        try:
            meta = json.loads((run_dir / "run.json").read_text(encoding="utf-8"))
        except (OSError, UnicodeDecodeError, ValueError) as exc:
            raise RigError(f"{run_dir / 'run.json'}: unreadable ({exc})") from None
        run_id = str(meta.get("id") or run_dir.name)
        uri = self.data.upload(run_dir, run_id, done=done)
        self.catalog.upsert_run(run_from_meta(meta, data=uri, samples=_rows(run_dir, meta),
                                              bench=bench_name(meta),
                                              operator=operator_name(meta)))
        (run_dir / MARKER).write_text(json.dumps({"store": self.store_key(), "data": uri}),
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


def pending_runs(spool: Path, publisher: Publisher) -> list[Path]:
    """Ended runs in ``spool`` not yet published to ``publisher``'s store, oldest first.
    A published run's marker is read, not its run.json (a bench's spool keeps every run)."""
    out = []
    for meta_path in sorted(Path(spool).glob("*/run.json")):
        if publisher.is_published(meta_path.parent):
            continue
        try:
            meta = json.loads(meta_path.read_text(encoding="utf-8"))
        except (OSError, UnicodeDecodeError, ValueError):
            continue
        if meta.get("status") != "running":
            out.append(meta_path.parent)
    return out
